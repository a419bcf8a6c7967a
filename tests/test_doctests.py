"""Runs the ``>>>`` examples in the docstrings of every library module (as installed: steer_envs.*)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

#: modules whose import needs something optional (Ray) or that run a CLI on import
_SKIP_PREFIXES = ("steer_envs.bench.__main__", "steer_envs.baselines.training.__main__", "steer_envs.ui.__main__")


def _library_modules() -> list[str]:
    # wrappers/ and baselines/ are mapped into steer_envs by setup.cfg, so they are walked from their own paths
    names = set()
    for root in ("steer_envs", "steer_envs.wrappers", "steer_envs.baselines"):
        package = importlib.import_module(root)
        names.add(root)
        for info in pkgutil.walk_packages(package.__path__, prefix=root + "."):
            if not info.name.startswith(_SKIP_PREFIXES):
                names.add(info.name)
    return sorted(names)


MODULES = _library_modules()


def test_every_layer_is_walked() -> None:
    for package in ("steer_envs.wrappers", "steer_envs.baselines", "steer_envs.bench", "steer_envs.envs"):
        assert any(name.startswith(package + ".") for name in MODULES), package


@pytest.mark.parametrize("module_name", MODULES)
def test_docstring_examples(module_name: str) -> None:
    module = importlib.import_module(module_name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(module, module_name):
        runner.run(test)
    failed, attempted = runner.summarize(verbose=False)
    assert failed == 0, f"{failed} of {attempted} doctest examples failed in {module_name}"
