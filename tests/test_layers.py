"""The house in layers: every import of the package (module level and inside functions) points down or sideways,
never up, and never in a cycle; optional extras are imported only where they are used."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "spn_torchrl"
BASE = {"errors", "config", "records", "checkpoint", "seeds", "lifecycle", "terminal"}
# rank of each room: a module may import its own rank or lower ones
RANKS = {"base": 0, "snn": 1, "envs": 1, "evaluation": 2, "training": 3, "analysis": 4, "tools": 4, "face": 5}
FACES = {"spn_torchrl", "spn_torchrl.run", "spn_torchrl.report", "spn_torchrl.play", "spn_torchrl.export"}
FACES.add("spn_torchrl.policies")
OPTIONAL = {"ray": {"spn_torchrl.evaluation.ray"}, "nir": set(), "imageio": set(), "wandb": set()}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def room(module: str) -> str:
    if module in FACES:
        return "face"
    parts = module.split(".")
    return "base" if parts[1] in BASE else parts[1]


def imports(module: str) -> list[tuple[str, int, bool]]:
    """(imported spn_torchrl module or optional extra, line, at module level) for every import statement."""
    tree = ast.parse(MODULES[module].read_text())
    top = {id(node) for node in tree.body}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [
                f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES else node.module for a in node.names
            ]
        else:
            continue
        for name in names:
            target = name if name in MODULES else name.rsplit(".", 1)[0] if name.startswith("spn_torchrl") else name
            found.append((target, node.lineno, id(node) in top))
    return found


def edges() -> list[tuple[str, str, int]]:
    return [
        (module, target, line)
        for module in MODULES
        for target, line, _ in imports(module)
        if target.startswith("spn_torchrl") and target != module
    ]


def test_every_import_points_down_or_sideways():
    bad = []
    for module, target, line in edges():
        a, b = room(module), room(target)
        if RANKS[b] > RANKS[a] or (a in ("analysis", "tools") and b == "training"):
            bad.append(f"{module}:{line} ({a}) imports {target} ({b})")
        if target == "spn_torchrl.run" and module != "spn_torchrl":
            bad.append(f"{module}:{line} imports spn_torchrl.run: only the package face may")
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    graph: dict[str, set[str]] = {}
    for module, target, _ in edges():
        if room(module) != "face":
            graph.setdefault(module, set()).add(target)
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            assert state.get(nxt) != 1, "import cycle: " + " -> ".join([*path, node, nxt])
            if nxt not in state:
                visit(nxt, [*path, node])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [])


def test_optional_extras_are_imported_lazily():
    bad = []
    for module in MODULES:
        for target, line, at_top in imports(module):
            root = target.split(".")[0]
            if root in OPTIONAL and at_top and module not in OPTIONAL[root]:
                bad.append(f"{module}:{line} imports {target} at module level")
    assert not bad, "\n".join(bad)


def test_each_module_says_what_it_is_for():
    missing = [m for m, p in MODULES.items() if not ast.get_docstring(ast.parse(p.read_text()))]
    assert not missing, missing


if __name__ == "__main__":  # the layer map, for README and review
    for module in sorted(MODULES):
        down = sorted({t for m, t, _ in edges() if m == module})
        print(f"{module:40s} [{room(module)}] -> {', '.join(down) or '-'}")
