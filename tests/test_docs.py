"""The documentation stays true to the code and to its readers.

* Snippets use the public API: no ```python block of the README or the docs
  site, and no example script, imports ``steer_envs.bench`` (steer-bench's
  suites are a client of the library, not its API).
* The docs site's snippets run. Convention: every ```python block in
  ``docs/**/*.md`` runs, on its own (each block does its own imports), unless
  the line before its fence is ``<!-- no-run -->``; ``<!-- slow -->`` there
  marks it slow (over ~30 s: run with ``-m slow``); ``<!-- interop -->`` marks
  a block that needs LeRobot: it runs in ``scripts/test_interop.sh``
  (tests/interop/test_interop_docs.py), not here. ``pycon`` blocks are
  examples with output and do not run here. The README's blocks run in
  ``tests/test_readme.py``.
* The README reads as a README: no dates, no issue references, no table cell
  over 300 characters.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
EXAMPLES = ROOT / "examples"

NO_RUN = "<!-- no-run -->"
SLOW = "<!-- slow -->"
INTEROP = "<!-- interop -->"
MAX_CELL = 300

_FENCE = re.compile(r"^(?P<indent>[ \t]*)```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$", re.M | re.S)
_BENCH_IMPORT = re.compile(
    r"^\s*(?:import\s+steer_envs\.bench\b|from\s+steer_envs\.bench\b|from\s+steer_envs\s+import\s+[^\n#]*\bbench\b)"
    r"|\bimport_module\(\s*[\"']steer_envs\.bench\b",
    re.M,
)
_MONTH = (
    r"(?:Jan(?:uary)?|Feb(?:ruary)?|Mar(?:ch)?|Apr(?:il)?|May|June?|July?|Aug(?:ust)?"
    r"|Sep(?:t(?:ember)?)?|Oct(?:ober)?|Nov(?:ember)?|Dec(?:ember)?)"
)
_DATE = re.compile(
    rf"\b\d{{4}}-\d{{2}}-\d{{2}}\b|\b{_MONTH}\.?\s+(?:\d{{1,2}},?\s+)?\d{{4}}\b|\b\d{{1,2}}\s+{_MONTH}\s+\d{{4}}\b"
)
# "PR" alone is not checked: it is the post-hoc ranking sampler's name ("PR 76/23/21")
_ISSUE = re.compile(r"(?<![\w&/])#\d+\b|\b(?:issues?|pull requests?)\s+#?\d+\b", re.I)


class Block(NamedTuple):
    path: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    marker: str  # the comment line right before the fence, if any

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def code_blocks(path: Path) -> list[Block]:
    """The fenced code blocks of a Markdown file, with the marker comment before each (if any)."""
    text = path.read_text(encoding="utf-8")
    blocks = []
    for match in _FENCE.finditer(text):
        before = [line.strip() for line in text[: match.start()].splitlines() if line.strip()]
        marker = before[-1] if before and before[-1].startswith("<!--") else ""
        indent = match.group("indent")
        body = "\n".join(line.removeprefix(indent) for line in match.group("body").splitlines())
        line = text.count("\n", 0, match.start()) + 1
        blocks.append(Block(path, line, match.group("lang"), body, marker))
    return blocks


def doc_pages() -> list[Path]:
    return sorted(DOCS.rglob("*.md"))


def python_blocks(paths: list[Path]) -> list[Block]:
    return [b for p in paths for b in code_blocks(p) if b.lang in ("python", "py")]


def _runnable() -> list[Any]:
    params = []
    for block in python_blocks(doc_pages()):
        if block.marker in (NO_RUN, INTEROP):
            continue
        marks = [pytest.mark.slow] if block.marker == SLOW else []
        params.append(pytest.param(block, id=block.name, marks=marks))
    return params


# --- snippets use the public API -------------------------------------------------------------


@pytest.mark.parametrize("block", python_blocks([README, *doc_pages()]), ids=lambda b: b.name)
def test_snippet_does_not_import_steer_bench(block: Block) -> None:
    assert not _BENCH_IMPORT.search(block.code), f"{block.name} imports steer_envs.bench; use the library's public API"


@pytest.mark.parametrize("script", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_example_does_not_import_steer_bench(script: Path) -> None:
    hits = [line for line in script.read_text(encoding="utf-8").splitlines() if _BENCH_IMPORT.search(line)]
    assert not hits, f"examples/{script.name} imports steer_envs.bench: {hits}"


def test_bench_import_pattern() -> None:
    for bad in (
        "from steer_envs.bench.suites.tli import protocol",
        "import steer_envs.bench",
        "from steer_envs import bench, io",
    ):
        assert _BENCH_IMPORT.search(bad), bad
    for fine in ("import steer_envs", "from steer_envs import wrappers", "# run `steer-bench run quick`"):
        assert not _BENCH_IMPORT.search(fine), fine


# --- the docs site's snippets run ------------------------------------------------------------


def test_docs_have_runnable_snippets() -> None:
    guides = {b.path.name for b in python_blocks(sorted((DOCS / "guides").glob("*.md"))) if b.marker != NO_RUN}
    assert {"itps.md", "tli.md", "glide.md", "recipes.md"} <= guides


@pytest.mark.parametrize("block", _runnable())
def test_docs_snippet_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib
    import torch

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)  # a snippet that writes files writes them here
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        exec(compile(block.code, block.name, "exec"), {"__name__": "__docs__"})
    finally:
        torch.set_num_threads(threads)


def test_code_blocks_reads_markers(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("text\n\n<!-- no-run -->\n```python\nx = 1\n```\n\n- item\n\n    ```python\n    y = 2\n    ```\n")
    first, second = code_blocks(page)
    assert (first.marker, first.code, first.line) == (NO_RUN, "x = 1", 4)
    assert (second.marker, second.code) == ("", "y = 2")


# --- the README reads as a README ------------------------------------------------------------


def _prose_lines(path: Path) -> list[tuple[int, str]]:
    return list(enumerate(path.read_text(encoding="utf-8").splitlines(), start=1))


def test_readme_has_no_dates() -> None:
    hits = [f"{n}: {line}" for n, line in _prose_lines(README) if _DATE.search(line)]
    assert not hits, "README lines with a date (history belongs in CHANGELOG.md):\n" + "\n".join(hits)


def test_readme_has_no_issue_references() -> None:
    hits = [f"{n}: {line}" for n, line in _prose_lines(README) if _ISSUE.search(line)]
    assert not hits, "README lines with an issue reference:\n" + "\n".join(hits)


def _cells(line: str) -> list[str]:
    row = line.strip()
    if not row.startswith("|"):
        return []
    parts = re.split(r"(?<!\\)\|", row.strip("|"))
    return [cell.strip() for cell in parts]


def test_readme_table_cells_are_short() -> None:
    long = [
        f"{n}: {len(cell)} characters: {cell[:80]}..."
        for n, line in _prose_lines(README)
        for cell in _cells(line)
        if len(cell) > MAX_CELL
    ]
    assert not long, f"README table cells over {MAX_CELL} characters:\n" + "\n".join(long)


def test_readme_checks_catch_what_they_should() -> None:
    for dated in ("measured 2026-12-05", "in December 2026", "on 5 Dec 2026", "Dec. 5, 2026"):
        assert _DATE.search(dated), dated
    for issue in ("see issue #17", "issue 16", "(#22)", "issues 21 and 17"):
        assert _ISSUE.search(issue), issue
    fine_lines = (
        "## Quickstart",
        "SAC at 100k steps",
        "Fig. 3.5",
        "PR 76/23 (33/100)",
        "[r](results.md#steer-ui)",
        "&#124;",
    )
    for fine in fine_lines:
        assert not (_DATE.search(fine) or _ISSUE.search(fine)), fine
    assert _cells("| a | b \\| c |") == ["a", "b \\| c"]


# --- the site's helpers ----------------------------------------------------------------------


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, DOCS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_griffe_extension_fences_doctests_and_reads_package_dir() -> None:
    pytest.importorskip("griffe")
    ext = _load("griffe_steer_envs")
    text = "Use :class:`~pkg.Foo` or :func:`bar`.\n\n>>> [1][0]\n1\n\nAfter."
    assert ext.markdown_docstring(text) == "Use `pkg.Foo` or `bar`.\n\n```pycon\n>>> [1][0]\n1\n```\n\nAfter."
    fenced = "```python\nx = ':class:`A`'\n```"
    assert ext.markdown_docstring(fenced) == fenced
    table = "Keys::\n\n    x = 1\n\n===  =====\nkey  means\n===  =====\n``a``  one\n     more\nb    two\n===  =====\n"
    assert ext.markdown_docstring(table) == (
        "Keys:\n\n    x = 1\n\n| key | means |\n|---|---|\n| ``a`` | one more |\n| b | two |"
    )
    assert ext.package_dirs() == {"steer_envs.wrappers": ROOT / "wrappers", "steer_envs.baselines": ROOT / "baselines"}
