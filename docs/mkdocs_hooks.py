"""mkdocs hooks: the repository's ``CHANGELOG.md`` is also the site's changelog page.

The Markdown files link to ``../CHANGELOG.md`` (the file beside the README),
which works when they are read in the repository. The site has no such file,
so ``mkdocs build --strict`` would fail on those links. These hooks add a
generated page ``changelog.md`` with the changelog's text (its links to
``docs/...`` made site-relative) and point every link that reaches the
repository's ``CHANGELOG.md`` at it. Used by ``mkdocs.yml`` (``hooks``); not
part of the installed package.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
CHANGELOG = ROOT / "CHANGELOG.md"
PAGE = "changelog.md"
_LINK = re.compile(r"\]\(((?:\.\./)+)CHANGELOG\.md(#[^)\s]*)?\)")


def on_files(files: Files, config: Any) -> Files:
    text = re.sub(r"\]\(docs/", "](", CHANGELOG.read_text(encoding="utf-8"))
    files.append(File.generated(config, PAGE, content=text))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    depth = page.file.src_uri.count("/")

    def relink(match: re.Match[str]) -> str:
        if len(match.group(1)) // 3 != depth + 1:  # not the repository root's CHANGELOG.md
            return match.group(0)
        return f"]({'../' * depth}{PAGE}{match.group(2) or ''})"

    return _LINK.sub(relink, markdown)
