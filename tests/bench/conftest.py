"""Fixtures of the steer-bench tests: the test-only ``toy`` plugin suite (tests/bench on sys.path), saved figures."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # the plugin module must import under any --import-mode
    sys.path.insert(0, str(HERE))

PLUGIN = "steer_bench_testplugin"


@pytest.fixture
def toy_suite():
    """The registered ``toy`` suite (imports the plugin module)."""
    from steer_envs.bench.suite import load_plugins

    load_plugins([PLUGIN])
    from steer_bench_testplugin import TOY

    return TOY


@pytest.fixture
def saved(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Any]]:
    """The figures saved while the test runs (``save_figure`` and ``fig.savefig`` both end in ``Figure.savefig``)."""
    from matplotlib.figure import Figure

    figures: list[Any] = []
    original = Figure.savefig

    def capture(self: Any, *args: Any, **kwargs: Any) -> Any:
        figures.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", capture)
    yield figures
