"""The docs' ``<!-- interop -->`` snippets (they need LeRobot) run here, each on its own."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_docs import DOCS, INTEROP, Block, python_blocks

BLOCKS = [b for b in python_blocks(sorted(DOCS.rglob("*.md"))) if b.marker == INTEROP]


def test_there_are_interop_snippets() -> None:
    assert any(b.path.name == "plug-in.md" for b in BLOCKS)


@pytest.mark.parametrize("block", BLOCKS, ids=lambda b: b.name)
def test_interop_snippet_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(block.code, block.name, "exec"), {"__name__": "__docs__"})
