"""MkDocs hooks: the configuration page's tables, generated at build time from ``spn_torchrl/config.py``, and the
committed reports (``reproduction/README.md``, ``beyond/report.md`` and their figures) as pages of the site.

Each field's documentation is the comment on its line or the comment lines just above it, ending in
``source: WHERE``; its default comes from the dataclass, its allowed range from the field's own ``validate``
(the sentence a bad value gets). New dataclass fields appear without any change here; a field without a
comment or a source is a warning, which ``mkdocs build --strict`` turns into a failed build.
"""

from __future__ import annotations

import ast
import copy
import dataclasses
import inspect
import io
import logging
import sys
import tokenize
import typing
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # this checkout's config.py, not another installed copy

from omegaconf import MISSING, OmegaConf  # noqa: E402

from spn_torchrl import config as C  # noqa: E402
from spn_torchrl.errors import ConfigError  # noqa: E402

log = logging.getLogger("mkdocs.hooks.config_tables")
MARKER = "<!-- config-tables -->"
OPTIONS_MARKER = "<!-- config-options -->"
# committed report files published as pages of the site: the reproduction and the study beyond the paper
PUBLISHED = {"reproduction": ("README.md", "*.png", "v2/*.png"), "beyond": ("report.md", "*.png")}
GROUPS = ("algo", "env", "evaluator", "logger")


@dataclasses.dataclass
class FieldDoc:
    path: str  # e.g. "algo.snn.hidden"
    default: str
    allowed: str
    what: str
    source: str


def comments() -> dict[tuple[str, str], str]:
    """(class, field) -> its comment: the one on the field's line, after the comment lines just above it."""
    path = Path(inspect.getsourcefile(C))
    text = path.read_text()
    by_line: dict[int, str] = {}
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            by_line[tok.start[0]] = tok.string.lstrip("#").strip()
    lines = text.splitlines()
    found = {}
    for node in ast.parse(text).body:
        if not isinstance(node, ast.ClassDef):
            continue
        for item in node.body:
            if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                parts = []
                above = item.lineno - 1
                while above >= 1 and lines[above - 1].strip().startswith("#"):
                    parts.insert(0, by_line[above])
                    above -= 1
                parts += [by_line[n] for n in range(item.lineno, item.end_lineno + 1) if n in by_line]
                found[(node.name, item.target.id)] = " ".join(parts)
    return found


def split_source(comment: str) -> tuple[str, str]:
    """A comment's description and its source (the text after its last ``source:``; empty if none)."""
    what, sep, source = comment.rpartition("source:")
    if not sep:
        return comment.strip(), ""
    return what.strip().rstrip(";").strip(), source.strip()


def show(value: Any) -> str:
    if value is MISSING or value == MISSING:
        return "set by its conf/ YAML"
    if dataclasses.is_dataclass(value):
        return f"`{type(value).__name__}` (below)"
    if value is None:
        return "`null`"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    return f"`{value}`"


def default_of(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return MISSING


def valid_instance(cls: type) -> Any:
    """An instance of ``cls`` whose every field passes validation: its defaults, required names filled in."""
    if cls is C.RunConfig:
        env = C.EnvConfig(name="cartpole", id="CartPole-v1")
        return C.RunConfig(C.GAConfig(), env, C.LoggerConfig(), C.LocalEvaluatorConfig())
    filled = {f.name: "x" for f in dataclasses.fields(cls) if default_of(f) is MISSING}
    return cls(**filled)


def validator(cls: type, at: str):
    if cls is C.RunConfig:
        return lambda obj: obj.__post_init__()
    if hasattr(cls, "validate"):
        return lambda obj: obj.validate(at)
    return None


def allowed(cls: type, at: str, f: dataclasses.Field, hint: Any) -> str:
    """The range a bad value of the field is told (its validator's own sentence), else its type."""
    if dataclasses.is_dataclass(hint):
        return "its fields below"
    check = validator(cls, at)
    name = f"{at}.{f.name}" if at else f.name
    if check is not None:
        probe = copy.copy(valid_instance(cls))
        object.__setattr__(probe, f.name, object())
        try:
            check(probe)
        except ConfigError as err:
            head = f"{name} must be "
            message = str(err)
            if message.startswith(head):
                text = message[len(head) :].rsplit(", got ", 1)[0]
                return f"{text}, or null" if _optional(hint) else text
        except Exception:  # a check that cannot read the probe: fall back to the type
            pass
    base = next((a for a in typing.get_args(hint) if a is not type(None)), hint) if _optional(hint) else hint
    names = {bool: "true or false", str: "a string", int: "an integer", float: "a number"}
    text = names.get(base, "see the description")
    return f"{text}, or null" if _optional(hint) else text


def _optional(hint: Any) -> bool:
    return typing.get_origin(hint) is typing.Union and type(None) in typing.get_args(hint)


def schema_paths() -> list[tuple[str, type]]:
    """(config path, dataclass) for every schema a run composes, then any other dataclass of the module."""
    order: list[tuple[str, type]] = [("", C.RunConfig)]
    hints = typing.get_type_hints(C.RunConfig)
    for f in dataclasses.fields(C.RunConfig):
        if f.name in C.SCHEMAS:
            order += [(f.name, cls) for cls in C.SCHEMAS[f.name].values()]
        elif dataclasses.is_dataclass(hints[f.name]):
            order.append((f.name, hints[f.name]))
    i = 1
    while i < len(order):  # nested dataclasses (algo.snn) right after their parent
        at, cls = order[i]
        nested = [
            (f"{at}.{f.name}", h)
            for f in dataclasses.fields(cls)
            if dataclasses.is_dataclass(h := typing.get_type_hints(cls)[f.name])
        ]
        order[i + 1 : i + 1] = [n for n in nested if n not in order]
        i += 1
    seen = {cls for _, cls in order}
    for _, cls in inspect.getmembers(C, inspect.isclass):
        if dataclasses.is_dataclass(cls) and cls.__module__ == C.__name__ and cls not in seen:
            order.append((cls.__name__, cls))
    return order


def field_docs() -> dict[str, list[FieldDoc]]:
    """Per schema heading, one FieldDoc per field, in declaration order."""
    notes = comments()
    out: dict[str, list[FieldDoc]] = {}
    for at, cls in schema_paths():
        hints = typing.get_type_hints(cls)
        rows = []
        for f in dataclasses.fields(cls):
            what, source = split_source(notes.get((cls.__name__, f.name), ""))
            rows.append(
                FieldDoc(
                    path=f"{at}.{f.name}" if at else f.name,
                    default=show(default_of(f)),
                    allowed=allowed(cls, at, f, hints[f.name]),
                    what=what,
                    source=source,
                )
            )
        title = f"`{at}`: `{cls.__name__}`" if at else f"top level: `{cls.__name__}`"
        out[title] = rows
    return out


def undocumented() -> list[str]:
    """Fields whose comment lacks a description or a source."""
    return [d.path for rows in field_docs().values() for d in rows if not d.what or not d.source]


def cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def config_tables() -> str:
    lines = []
    for title, rows in field_docs().items():
        lines += [f"### {title}", "", "| field | default | allowed | what | source |", "|---|---|---|---|---|"]
        for d in rows:
            lines.append(
                f"| `{d.path}` | {cell(d.default)} | {cell(d.allowed)} | {cell(d.what) or '—'} | {cell(d.source) or '—'} |"
            )
        lines.append("")
    return "\n".join(lines)


def config_options() -> str:
    """Each option of each config group in conf/ and what its YAML sets beyond its schema's defaults."""
    lines = ["| group | option | sets |", "|---|---|---|"]
    for group in (*GROUPS, "experiment"):
        for path in sorted((ROOT / "conf" / group).glob("*.yaml")):
            node = OmegaConf.to_container(OmegaConf.load(path))
            node.pop("defaults", None)
            sweep = node.pop("hydra", {}).get("sweeper", {}).get("params", {})
            sets = [f"`{k}={v}`" for k, v in _flat(node)] + [f"sweeps `{k}={v}`" for k, v in sweep.items()]
            plus = "+" if group == "experiment" else ""  # a preset added to the defaults list
            lines.append(f"| `{group}` | `{plus}{group}={path.stem}` | {', '.join(sets) or 'the schema defaults'} |")
    return "\n".join(lines)


def _flat(node: dict, at: str = "") -> list[tuple[str, Any]]:
    out = []
    for key, value in node.items():
        name = f"{at}.{key}" if at else key
        out += _flat(value, name) if isinstance(value, dict) else [(name, value)]
    return out


# --- MkDocs hook entry points -------------------------------------------------------------------------------------


def on_files(files, config):
    """Publish reproduction/README.md and beyond/report.md (the report command's output, PREFACE.md at its top) and
    their figures."""
    from mkdocs.structure.files import File

    for folder, patterns in PUBLISHED.items():
        for path in sorted(path for pattern in patterns for path in (ROOT / folder).glob(pattern)):
            files.append(
                File(
                    path.relative_to(ROOT).as_posix(),
                    src_dir=str(ROOT),
                    dest_dir=config["site_dir"],
                    use_directory_urls=config["use_directory_urls"],
                )
            )
    return files


def on_page_markdown(markdown, page, config, files):
    if MARKER in markdown:
        for path in undocumented():
            log.warning(f"spn_torchrl/config.py: {path} has no comment with a description and a 'source:'")
        markdown = markdown.replace(MARKER, config_tables())
    if OPTIONS_MARKER in markdown:
        markdown = markdown.replace(OPTIONS_MARKER, config_options())
    return markdown
