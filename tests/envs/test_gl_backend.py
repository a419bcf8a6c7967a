"""The arm envs render without MUJOCO_GL set, from a worker thread too (what steer-ui does)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytest.importorskip("robosuite")

from steer_envs.envs.robosuite.gl_backend import CANDIDATES, ensure_gl_backend

SCRIPT = """
import os, threading
import gymnasium as gym
import steer_envs
env = gym.make("steer_envs/BlockStack-v0", render_mode="rgb_array")
env.reset(seed=0)
out = {}
thread = threading.Thread(target=lambda: out.update(rgbd=env.unwrapped.render_rgbd()))
thread.start()
thread.join()
rgb, depth = out["rgbd"]
print(os.environ["MUJOCO_GL"], rgb.shape, float(rgb.std()) > 0)
"""


def test_an_unset_backend_is_chosen_and_renders_from_a_worker_thread() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["OMP_NUM_THREADS"] = "1"
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    backend, *rest = done.stdout.split()
    assert backend in CANDIDATES and rest[-1] == "True"
    assert f"offscreen rendering uses {backend}" in done.stderr


def test_a_backend_the_user_chose_is_left_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert ensure_gl_backend() == "osmesa"
