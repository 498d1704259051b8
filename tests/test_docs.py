"""The documentation site: its configuration tables are generated from spn_torchrl/config.py at build time
(docs/hooks.py), so they cannot go stale; these tests hold that every field has a description and a source, that
the tables show each field's real default and range, and that every page the nav names exists.
``mkdocs build --strict`` (in .ci/run) builds the whole site."""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
hooks = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = hooks  # its dataclass looks itself up there
spec.loader.exec_module(hooks)


def rows() -> dict[str, hooks.FieldDoc]:
    return {d.path: d for docs in hooks.field_docs().values() for d in docs}


def test_every_field_has_a_description_and_a_source():
    assert hooks.undocumented() == []
    for d in rows().values():
        assert d.what and d.source, d.path


def test_every_field_of_every_schema_is_in_the_tables():
    tables = hooks.config_tables()
    for at, cls in hooks.schema_paths():
        for f in dataclasses.fields(cls):
            path = f"{at}.{f.name}" if at else f.name
            assert f"| `{path}` |" in tables, path


def test_tables_show_the_dataclass_defaults_and_the_validators_ranges():
    found = rows()
    assert found["algo.population"].default == "`200`"
    assert found["algo.snn.decay"].default == "`0.75`"
    assert found["algo.truncation"].allowed == "a finite number in (0, 1]"
    assert found["algo.genome"].allowed == "one of 'connections', 'weights'"
    assert found["algo.sigma"].source == "SPEC.md, GA (paper budget)"
    assert found["env.id"].default == "set by its conf/ YAML"


def test_a_field_without_a_source_is_reported(monkeypatch):
    notes = hooks.comments()
    notes[("GAConfig", "sigma")] = "mutation std of each gene"  # the comment, its source cut off
    monkeypatch.setattr(hooks, "comments", lambda: notes)
    assert hooks.undocumented() == ["algo.sigma"]


def test_the_configuration_page_asks_for_the_generated_tables():
    page = (ROOT / "docs" / "configuration.md").read_text()
    assert hooks.MARKER in page and hooks.OPTIONS_MARKER in page
    out = hooks.on_page_markdown(page, None, None, None)
    assert hooks.MARKER not in out and "| `algo.snn.hidden` | `64` |" in out
    assert "| `env` | `env=halfcheetah` |" in out


def pages(nav) -> list[str]:
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, dict):
        return [p for v in nav.values() for p in pages(v)]
    return [p for item in nav for p in pages(item)]


def test_every_nav_page_exists():
    site = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    for page in pages(site["nav"]):
        if page.split("/")[0] in hooks.PUBLISHED:  # published from reproduction/ or beyond/ by the hook
            assert (ROOT / page).is_file(), page
        else:
            assert (ROOT / "docs" / page).is_file(), page
