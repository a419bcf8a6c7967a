"""Fixtures of the steer-bench tests: the test-only ``toy`` plugin suite (tests/bench on sys.path)."""

from __future__ import annotations

import sys
from pathlib import Path

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
