"""``steer-ui --domain blockstack`` as installed, ``MUJOCO_GL`` unset: it picks a GL backend and serves clicks."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from typing import Any
from urllib.error import URLError
from urllib.request import urlopen

import numpy as np
import pytest

pytest.importorskip("uvicorn")
pytest.importorskip("websockets")
pytest.importorskip("robosuite")

from websockets.sync.client import ClientConnection, connect

from steer_envs.ui import Session
from steer_envs.utils.threads import limit_threads

SEED = 0
TIMEOUT = 300.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ask(ws: ClientConnection, message: dict[str, Any], until: str) -> dict[str, Any]:
    ws.send(json.dumps(message))
    while True:
        reply: dict[str, Any] = json.loads(ws.recv(timeout=TIMEOUT))
        if reply["type"] in (until, "error"):
            return reply


def _cube_pixel() -> list[float]:
    """Where cube 0 of the seed's scene is in the camera image (the server's session has the same scene)."""
    with limit_threads(1, 1):
        session = Session("blockstack", seed=SEED)
    try:
        return [float(v) for v in np.asarray(session.pixels.to_pixels(session.env.unwrapped.cube_pos[0]))]  # type: ignore[attr-defined]
    finally:
        session.close()


def test_blockstack_serves_a_click_with_mujoco_gl_unset() -> None:
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["OMP_NUM_THREADS"] = "1"
    cmd = [sys.executable, "-m", "steer_envs.ui", "--domain", "blockstack", "--seed", str(SEED), "--port", str(port)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + TIMEOUT
        while True:
            try:
                with urlopen(f"http://127.0.0.1:{port}/api/health", timeout=5) as health:
                    assert json.loads(health.read())["status"] == "ok"
                break
            except (URLError, ConnectionError):
                assert proc.poll() is None, proc.communicate()
                assert time.monotonic() < deadline, "steer-ui did not start in time"
                time.sleep(0.5)
        pixel = _cube_pixel()
        with connect(f"ws://127.0.0.1:{port}/ws") as ws:
            ready = _ask(ws, {"type": "hello"}, "ready")
            assert ready["type"] == "ready", ready
            plans = _ask(ws, {"type": "steer", "kind": "point", "points": [pixel]}, "plans")
            assert plans["type"] == "plans", plans
            assert len(plans["plans"]) > 0
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=60)
    assert "offscreen rendering uses" in err  # it says which backend it chose
    assert "Error" not in err, err[-3000:]
