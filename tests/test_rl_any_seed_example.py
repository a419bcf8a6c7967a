"""``examples/rl_any_seed.py``: --help, usage errors exit 2, a tiny SAC budget trains and evaluates end to end."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[1]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    script = str(ROOT / "examples" / "rl_any_seed.py")
    return subprocess.run(
        [sys.executable, script, *args], capture_output=True, text=True, timeout=300, env=env, cwd=ROOT
    )


def test_help_and_usage_errors() -> None:
    res = _run("--help")
    assert res.returncode == 0 and "--seed" in res.stdout and "--steps" in res.stdout
    for bad, name in (
        (("--steps", "0"), "--steps"),
        (("--seed", "-1"), "--seed"),
        (("--seed", "1000000"), "--seed"),
        (("--seed", "eleven"), "--seed"),
        (("--episodes", "0"), "--episodes"),
        (("--env", "steer_envs/PolygonNav-3Mode-v0"), "--env"),
    ):
        res = _run(*bad)
        assert res.returncode == 2 and name in res.stderr, (bad, res.stderr)


def test_a_tiny_budget_trains_and_evaluates_on_disjoint_seeds() -> None:
    res = _run("--seed", "11", "--steps", "300", "--episodes", "2")
    assert res.returncode == 0, res.stderr
    assert "steer_envs/PolygonNav-3ModeDense-v0: observation Box" in res.stdout
    assert "Box(-1.0, 1.0, (2,), float32)" in res.stdout  # the registered [-1, 1] actions
    assert "seed 11, budget 300 steps" in res.stdout
    match = re.search(
        r"success rate (\d+) % \((\d)/2 deterministic episodes, reset seeds 1000000\.\.1000001\)", res.stdout
    )
    assert match is not None, res.stdout
    assert int(match[1]) == 50 * int(match[2])
