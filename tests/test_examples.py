"""The examples run as documented (small settings) and write what they say they write."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"), "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, str(ROOT / "examples" / script), *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=ROOT,
    )


def test_envs_tour_saves_a_picture_per_env(tmp_path: Path) -> None:
    res = _run("envs_tour.py", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "PolygonNav-5Mode-v0   success=True" in res.stdout
    assert len(list(tmp_path.glob("*.png"))) >= 5


@pytest.mark.parametrize("sampler", ["SS", "OP"])
def test_steer_maze2d_writes_the_steered_rollout(tmp_path: Path, sampler: str) -> None:
    res = _run("steer_maze2d.py", "--sampler", sampler, "--batch", "4", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "min L2" in res.stdout
    (png,) = tmp_path.glob(f"steer_dp_{sampler}_seed0.png")
    assert png.stat().st_size > 10_000


def test_sb3_agent_drives_the_steering_wrapper(tmp_path: Path) -> None:
    res = _run("sb3_steering.py", "--steps", "8", "--batch", "2", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "a flattened 8-point sketch" in res.stdout
    assert (tmp_path / "ppo_steering.zip").stat().st_size > 0
    assert (tmp_path / "sb3_log" / "progress.csv").is_file()  # SB3 logs into --out, not the temp dir


def test_maze2d_examples_reject_a_missing_checkpoint(tmp_path: Path) -> None:
    for script in ("steer_maze2d.py", "sb3_steering.py"):
        res = _run(script, "--checkpoint", str(tmp_path / "absent.safetensors"), "--out", str(tmp_path))
        assert res.returncode == 2 and "no checkpoint file" in res.stderr


def test_glide_polygon_learns_modes_and_plans_through_them(tmp_path: Path) -> None:
    args = ("--modes", "3", "--layout", "1", "--replays", "150", "--epochs", "500", "--rollouts", "30", "--show", "4")
    res = _run("glide_polygon.py", *args, "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    # each phase is announced as it starts (a long training phase must not be silent) ...
    assert "training the mode classifier (500 epochs" in res.stdout and "evaluating GLiDE+Planning" in res.stdout
    assert "GLiDE classifier" not in res.stderr  # ... and no tqdm bar floods the (non-terminal) log
    overlap = float(res.stdout.split("overlap ")[1].split(",")[0])
    assert overlap > 0.9  # 150 + 150 replays already ground 3 modes (0.964 on this layout)
    success = float(res.stdout.split("without teleports: success ")[1].split(",")[0])
    assert success >= 0.8, res.stdout
    assert (tmp_path / "glide_3modes_layout1.png").stat().st_size > 10_000
    again = _run("glide_polygon.py", *args, "--out", str(tmp_path))  # the classifier comes from the cache
    assert again.returncode == 0 and "(cached)" in again.stdout
    bad = _run("glide_polygon.py", "--replays", "0", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--replays" in bad.stderr
    bad = _run("glide_polygon.py", "--max-steps", "0", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--max-steps" in bad.stderr


@pytest.mark.skipif(
    __import__("importlib").util.find_spec("robosuite") is None, reason="the robosuite extra is not installed"
)
def test_glide_robosuite_learns_modes_and_draws_them(tmp_path: Path) -> None:
    args = ("--task", "lift", "--demos", "2", "--replays", "2", "--epochs", "30", "--show", "2")
    res = _run("glide_robosuite.py", *args, "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "lift: 2 demos, 4 replays" in res.stdout and "kmeans: accuracy" in res.stdout
    assert (tmp_path / "glide_lift_modes.png").stat().st_size > 10_000
    assert _run("glide_robosuite.py", "--demos", "0").returncode == 2


def test_steer_blockstack_builds_part_of_a_tower_and_saves_the_strip(tmp_path: Path) -> None:
    args = ("--method", "DP-PR", "--batch", "4", "--max-skills", "2", "--order", "3,1,0,2")
    res = _run("steer_blockstack.py", *args, "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "skill 1: wanted pick_1" in res.stdout and "plans aligned" in res.stdout
    (png,) = tmp_path.glob("steer_blockstack_DP-PR_seed0.png")
    assert png.stat().st_size > 10_000
    res = _run("steer_blockstack.py", "--order", "0,1,2", "--out", str(tmp_path))
    assert res.returncode == 2 and "--order" in res.stderr


def test_steer_safely_compares_plain_and_safe_steering(tmp_path: Path) -> None:
    res = _run("steer_safely.py", "--starts", "2", "--batch", "4", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert "plain   Min L2" in res.stdout and "safety  Min L2" in res.stdout
    (png,) = tmp_path.glob("steer_safely_SS.png")
    assert png.stat().st_size > 10_000
    bad = _run("steer_safely.py", "--weight", "0")
    assert bad.returncode == 2 and "--weight" in bad.stderr
