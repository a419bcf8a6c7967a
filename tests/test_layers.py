"""Dependencies point one way (docs/architecture.md, "Layers") and never in a circle.

Every import in the library counts, lazy ones (inside functions) included:
a module may import only from layers of lower rank or its own layer, and no
chain of imports between modules may lead back to where it started.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: source folder -> installed package name
PACKAGES = {"steer_envs": "steer_envs", "wrappers": "steer_envs.wrappers", "baselines": "steer_envs.baselines"}
#: layer -> rank; a module may import only from layers of lower rank (and from its own layer)
RANKS = {
    "io": 0,
    "core": 1,
    "ltl": 2,
    "envs": 2,
    "control": 3,
    "data": 4,
    "users": 4,
    "utils": 4,
    "baselines": 5,
    "steering": 5,
    "adapters": 6,
    "wrappers": 6,
    "ui": 7,
    "bench": 8,
}


def _module_name(path: Path) -> str:
    folder = path.relative_to(ROOT).parts[0]
    rel = path.relative_to(ROOT / folder).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join([PACKAGES[folder], *parts])


def _layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "steer_envs" or len(parts) < 2:
        return None
    return parts[1]


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _absolute(path: Path, node: ast.ImportFrom) -> str:
    """The absolute module a (possibly relative) ``from ... import`` names."""
    if node.level == 0:
        return node.module or ""
    parts = _module_name(path).split(".")
    base = parts if _is_package(path) else parts[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def _imports(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every import in ``path``; ``from pkg import sub`` names ``pkg.sub`` when it is a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = _absolute(path, node)
            subs = [f"{module}.{alias.name}" for alias in node.names if f"{module}.{alias.name}" in MODULES]
            found += [(node.lineno, sub) for sub in subs] or [(node.lineno, module)]
    return found


SOURCES = sorted(p for folder in PACKAGES for p in (ROOT / folder).rglob("*.py"))
MODULES = {_module_name(p): p for p in SOURCES}


def test_every_layer_has_a_rank() -> None:
    layers = {_layer(_module_name(p)) for p in SOURCES} - {None}
    assert layers <= set(RANKS), f"unranked layers {sorted(layers - set(RANKS))}: add them to RANKS and the docs"


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down_the_layers(path: Path) -> None:
    module = _module_name(path)
    layer = _layer(module)
    if layer is None or layer not in RANKS:  # the root package (registers the envs)
        return
    bad = []
    for line, target in _imports(path):
        other = _layer(target)
        if other is None or other == layer:
            continue
        if other not in RANKS or RANKS[other] >= RANKS[layer]:
            bad.append(f"line {line}: {module} ({layer}) imports {target} ({other})")
    assert not bad, "imports against the layer order:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    "path",
    [p for p in SOURCES if "bench/suites/" in p.as_posix()],
    ids=lambda p: str(p.relative_to(ROOT)),
)
def test_suites_do_not_import_each_other(path: Path) -> None:
    module = _module_name(path)
    own = module.split(".")[3] if module.count(".") >= 3 else None  # steer_envs.bench.suites.<own>...
    bad = [
        f"line {line}: {target}"
        for line, target in _imports(path)
        if target.startswith("steer_envs.bench.suites.") and target.split(".")[3] != own
    ]
    assert not bad, f"{module} imports another suite (share code through a lower layer):\n" + "\n".join(bad)


def _import_graph() -> dict[str, set[str]]:
    """Module -> the library modules it imports (the nearest existing module for attribute imports)."""
    graph: dict[str, set[str]] = {}
    for module, path in MODULES.items():
        targets = set()
        for _, target in _imports(path):
            while target and target not in MODULES:
                target = target.rpartition(".")[0]
            if target and target != module:
                targets.add(target)
        graph[module] = targets
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module, each sorted, in sorted order."""
    import networkx as nx

    digraph = nx.DiGraph([(v, w) for v, targets in graph.items() for w in targets])
    digraph.add_nodes_from(graph)
    return sorted(sorted(c) for c in nx.strongly_connected_components(digraph) if len(c) > 1)


def test_cycle_finder_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles() -> None:
    cycles = _cycles(_import_graph())
    assert not cycles, "import cycles (lazy imports count):\n" + "\n".join(" <-> ".join(c) for c in cycles)
