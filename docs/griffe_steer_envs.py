"""Griffe extension: let the API reference see steer_envs as Python does.

Two things Griffe, which reads the source tree without importing it, would miss:

**Packages installed from another folder.** ``setup.cfg``'s ``package_dir``
installs ``wrappers/`` as ``steer_envs.wrappers`` and ``baselines/`` as
``steer_envs.baselines``. Python follows that mapping (the editable install's
finder does), but Griffe only finds ``steer_envs/`` and would miss both.
When Griffe has visited ``steer_envs/__init__.py``, this extension visits
each mapped folder as the named subpackage, with the same collections and
extensions, so ``::: steer_envs.wrappers`` and cross-references resolve as
they do in Python.
The mapping is read from ``setup.cfg``, so it is never written twice.

**Lazy exports.** Packages that import their names on first use (a module-level
``_EXPORTS = {"Name": "submodule", ...}`` read by ``__getattr__``, so that
importing the package stays cheap) get each name as an alias of
``package.submodule.Name``, the object ``from package import Name`` returns.

**reST in docstrings.** The docstrings are Google style with reST touches:
``>>>`` examples in the running text (tested by ``tests/test_doctests.py``)
become ``pycon`` code blocks, so Markdown neither quotes the examples nor
reads their brackets as links; roles such as ``:class:`X``` render as code
``X``; reST simple tables (``===`` rules) become Markdown tables.

Used by ``mkdocs.yml`` (``plugins: mkdocstrings: handlers: python: options:
extensions``); not part of the installed package.
"""

from __future__ import annotations

import ast
import configparser
import re
from pathlib import Path
from typing import Any

import griffe

ROOT = Path(__file__).resolve().parents[1]

_ROLE = re.compile(r":(?:class|func|meth|mod|attr|data|exc|obj|const|py:\w+):`~?\.?([^`]+)`")


def markdown_docstring(text: str) -> str:
    """``text`` as Markdown: ``>>>`` runs fenced as ``pycon``, reST roles as code, reST simple tables as tables.

    A paragraph's closing ``::`` (reST: "a literal block follows") becomes ``:``;
    the indented block after it is a code block in Markdown too.
    ``tests/test_docs.py`` has examples.
    """
    out: list[str] = []
    fence: str | None = None  # the indentation of the open doctest block
    in_code = False
    lines = _tables(text.splitlines())
    for line in lines:
        stripped = line.lstrip()
        indent = line[: len(line) - len(stripped)]
        if fence is not None and (not stripped or not line.startswith(fence)):
            out.append(f"{fence}```")
            fence = None
        if stripped.startswith("```"):
            in_code = not in_code
        elif fence is None and not in_code and stripped.startswith(">>>"):
            out.append(f"{indent}```pycon")
            fence = indent
        if fence is None and not in_code:
            line = _ROLE.sub(r"`\1`", line)
            if line.endswith("::") and not stripped.startswith("::"):
                line = line[:-1]
        out.append(line)
    if fence is not None:
        out.append(f"{fence}```")
    return "\n".join(out)


_RULE = re.compile(r"^(\s*)(=+)( +=+)+\s*$")


def _tables(lines: list[str]) -> list[str]:
    """Each reST simple table (``===  ===`` rules around a header and rows) as a Markdown table."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        rule = _RULE.match(lines[i])
        ends = [j for j in range(i + 1, min(len(lines), i + 200)) if _RULE.match(lines[j]) and lines[j] == lines[i]]
        if not rule or len(ends) < 2:
            out.append(lines[i])
            i += 1
            continue
        spans = [(m.start(), m.end()) for m in re.finditer(r"=+", lines[i])]
        rows: list[list[str]] = []
        for line in lines[i + 1 : ends[1]]:
            if line == lines[i] or not line.strip():
                continue
            cells = [
                line[a : (spans[k + 1][0] if k + 1 < len(spans) else len(line))].strip()
                for k, (a, _) in enumerate(spans)
            ]
            if rows and not cells[0]:  # a continuation line: its text joins the row above
                rows[-1] = [f"{old} {new}".strip() for old, new in zip(rows[-1], cells, strict=True)]
            else:
                rows.append(cells)
        indent = rule.group(1)
        out.append(f"{indent}| " + " | ".join(rows[0]) + " |")
        out.append(f"{indent}|" + "---|" * len(spans))
        out.extend(f"{indent}| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows[1:])
        i = ends[1] + 1
    return out


def package_dirs(setup_cfg: Path = ROOT / "setup.cfg") -> dict[str, Path]:
    """The ``package_dir`` entries of ``setup.cfg`` that name a subpackage, as absolute folders."""
    parser = configparser.ConfigParser()
    parser.read(setup_cfg, encoding="utf-8")
    raw = parser.get("options", "package_dir", fallback="")
    mapping: dict[str, Path] = {}
    for line in raw.splitlines():
        name, sep, folder = line.partition("=")
        if sep and "." in name.strip():
            mapping[name.strip()] = (setup_cfg.parent / folder.strip()).resolve()
    return mapping


class PackageDir(griffe.Extension):
    """Attach every ``package_dir`` subpackage to its parent package once the parent is visited."""

    def __init__(self) -> None:
        super().__init__()
        self.mapping = package_dirs()

    def on_instance(self, *, node: ast.AST | griffe.ObjectNode, obj: griffe.Object, agent: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown_docstring(obj.docstring.value)

    def on_module_members(
        self, *, node: ast.AST | griffe.ObjectNode, mod: griffe.Module, agent: Any, **kwargs: Any
    ) -> None:
        for dotted, folder in self.mapping.items():
            parent_path, _, name = dotted.rpartition(".")
            if parent_path == mod.path and name not in mod.members:
                self._visit_package(name, folder, mod, agent)
        if isinstance(node, ast.Module):
            self._add_lazy_exports(node, mod)

    @staticmethod
    def _add_lazy_exports(node: ast.Module, mod: griffe.Module) -> None:
        exports: dict[str, str] = {}
        for statement in node.body:
            target = statement.targets[0] if isinstance(statement, ast.Assign) else getattr(statement, "target", None)
            value = getattr(statement, "value", None)
            if isinstance(target, ast.Name) and target.id == "_EXPORTS" and isinstance(value, ast.Dict):
                exports = ast.literal_eval(value)
        for name, submodule in exports.items():
            if name not in mod.members:
                mod.set_member(name, griffe.Alias(name, f"{mod.path}.{submodule}.{name}", parent=mod))
        if exports and mod.exports is None:  # ``__all__`` computed from _EXPORTS: Griffe cannot evaluate it
            mod.exports = list[str | griffe.ExprName](sorted(exports))

    def _visit_package(self, name: str, folder: Path, parent: griffe.Module, agent: Any) -> None:
        package = self._visit_file(name, folder / "__init__.py", parent, agent)
        parent.set_member(name, package)
        for path in sorted(folder.iterdir()):
            if path.is_dir() and (path / "__init__.py").is_file():
                self._visit_package(path.name, path, package, agent)
            elif path.suffix == ".py" and path.name != "__init__.py" and "." not in path.stem:
                package.set_member(path.stem, self._visit_file(path.stem, path, package, agent))

    @staticmethod
    def _visit_file(name: str, path: Path, parent: griffe.Module, agent: Any) -> griffe.Module:
        code = path.read_text(encoding="utf-8-sig")
        agent.lines_collection[path] = code.splitlines(keepends=False)
        return griffe.visit(
            name,
            filepath=path,
            code=code,
            extensions=agent.extensions,
            parent=parent,
            docstring_parser=agent.docstring_parser,
            docstring_options=agent.docstring_options,
            lines_collection=agent.lines_collection,
            modules_collection=agent.modules_collection,
        )
