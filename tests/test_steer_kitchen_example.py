"""``examples/steer_kitchen.py``: --help, usage errors and a missing policy exit 2, one click with a tiny policy."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"), "OMP_NUM_THREADS": "1"}
    script = str(ROOT / "examples" / "steer_kitchen.py")
    return subprocess.run(
        [sys.executable, script, *args], capture_output=True, text=True, timeout=300, env=env, cwd=ROOT
    )


def test_help_and_usage_errors(tmp_path: Path) -> None:
    res = _run("--help")
    assert res.returncode == 0 and "--pixel U V" in res.stdout and "--method" in res.stdout
    for bad in (("--pixel", "300", "1"), ("--pixel", "1"), ("--method", "DP-XX"), ("--batch", "0")):
        res = _run(*bad, "--out", str(tmp_path))
        assert res.returncode == 2, bad
    res = _run("--checkpoint", str(tmp_path / "absent.safetensors"), "--out", str(tmp_path))
    assert res.returncode == 2 and "not available" in res.stderr


@pytest.mark.skipif(importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed")
def test_a_click_steers_one_skill_and_saves_the_strip(tmp_path: Path) -> None:
    sys.path.insert(0, str(ROOT / "tests" / "steering"))
    try:
        from test_kitchen_steering import tiny_policy
    finally:
        sys.path.pop(0)
    checkpoint = tiny_policy().save(tmp_path / "tiny.safetensors")
    res = _run(
        "--pixel",
        "117",
        "151",
        "--method",
        "DP-GD",
        "--batch",
        "2",
        "--checkpoint",
        str(checkpoint),
        "--out",
        str(tmp_path),
    )
    assert res.returncode == 0, res.stderr
    assert "skill 1: click (117, 151) -> point" in res.stdout
    (png,) = tmp_path.glob("steer_kitchen_DP-GD_seed0.png")
    assert png.stat().st_size > 10_000
