"""Helpers of the steer-bench tests: run ``python -m steer_envs.bench`` in a subprocess, find its processes;
a suite's trial; check saved figures; a data suite's count and cache parameters."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

HERE = Path(__file__).resolve().parent

#: skips a test when the robosuite extra is not installed
needs_robosuite = pytest.mark.skipif(
    importlib.util.find_spec("robosuite") is None, reason="the robosuite extra is not installed"
)


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


def _process_table() -> dict[int, tuple[str, int]]:
    """pid -> (state, parent pid) of every process (psutil when installed, else /proc)."""
    try:
        import psutil
    except ImportError:
        psutil = None
    table: dict[int, tuple[str, int]] = {}
    if psutil is not None:
        for proc in psutil.process_iter(["pid", "ppid", "status"]):
            info = proc.info
            state = "Z" if info["status"] in (psutil.STATUS_ZOMBIE, psutil.STATUS_DEAD) else "R"
            table[info["pid"]] = (state, info["ppid"])
        return table
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        table[int(entry.name)] = (fields[0], int(fields[1]))
    return table


def descendants(pid: int) -> set[int]:
    """Every living process below ``pid`` (children, grandchildren, ...)."""
    table = _process_table()
    found: set[int] = set()
    frontier = [pid]
    while frontier:
        parent = frontier.pop()
        for child, (state, ppid) in table.items():
            if ppid == parent and child not in found and state not in ("Z", "X"):
                found.add(child)
                frontier.append(child)
    return found


def alive(pids: set[int]) -> set[int]:
    """The processes of ``pids`` that still run (zombies count as gone)."""
    table = _process_table()
    return {p for p in pids if p in table and table[p][0] not in ("Z", "X")}


def wait_gone(pids: set[int], timeout: float = 5.0) -> set[int]:
    """Wait until none of ``pids`` runs (at most ``timeout`` seconds); returns the survivors."""
    deadline = time.monotonic() + timeout
    survivors = alive(pids)
    while survivors and time.monotonic() < deadline:
        time.sleep(0.05)
        survivors = alive(survivors)
    return survivors


def kill_all(pids: set[int]) -> None:
    """SIGKILL each of ``pids`` that still runs (cleanup after a failed orphan check)."""
    for pid in alive(pids):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def suite_trial(suite_name: str, method: str | None, seed: int, **overrides: Any) -> Any:
    """The trial of registered suite ``suite_name`` on its first env, with ``overrides`` of its parameters."""
    from steer_envs.bench.suite import get_suite

    suite = get_suite(suite_name)
    return suite.trial(suite.env_list()[0], method, seed, suite.resolve_params(overrides))


def check_data_params(params_type: Any, count: str, cache_name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A data suite's parameters refuse a ``count`` of 0 or of text and a ``cache_dir`` not text; the cache
    defaults to ``$XDG_CACHE_HOME/steer-envs/<cache_name>`` and takes ``cache_dir`` as given."""
    with pytest.raises(ValueError, match=count):
        params_type(**{count: 0})
    with pytest.raises(ValueError, match=count):
        params_type.from_json({count: "many"})
    with pytest.raises(ValueError, match="cache_dir"):
        params_type.from_json({"cache_dir": 3})
    monkeypatch.setenv("XDG_CACHE_HOME", "/tmp/xdg")
    assert params_type().cache == f"/tmp/xdg/steer-envs/{cache_name}"
    assert params_type(cache_dir="/x").cache == "/x"


def check_figures(figures: list[Any], count: int) -> None:
    """``count`` figures were saved, and none misses a title, a legend or axis labels (``figure_problems``)."""
    from steer_envs.bench.plots import figure_problems

    assert len(figures) == count
    for fig in figures:
        assert figure_problems(fig) == [], fig._suptitle.get_text() if fig._suptitle else fig.axes[0].get_title()
