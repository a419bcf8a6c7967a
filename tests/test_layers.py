"""Dependencies point one way (docs/architecture.md, "Layers"): every import in the library, lazy ones included."""

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
    "users": 3,
    "data": 3,
    "utils": 3,
    "wrappers": 4,
    "baselines": 5,
    "ui": 6,
    "bench": 7,
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


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


SOURCES = sorted(p for folder in PACKAGES for p in (ROOT / folder).rglob("*.py"))


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
