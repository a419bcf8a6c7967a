"""Helpers of the steer-bench tests: run ``python -m steer_envs.bench`` in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def bench_env() -> dict[str, str]:
    """Environment for a ``python -m steer_envs.bench`` subprocess that can import the plugin."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.pop("STEER_BENCH_PLUGINS", None)
    return env


def run_cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """``python -m steer_envs.bench ARGS`` in a subprocess (captures output)."""
    return subprocess.run(
        [sys.executable, "-m", "steer_envs.bench", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=bench_env(),
    )
