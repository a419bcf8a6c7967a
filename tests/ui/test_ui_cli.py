"""``steer-ui`` command line: help, usage errors (exit 2), a real start that serves the page."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from urllib.error import URLError
from urllib.request import urlopen

import pytest

from steer_envs.ui.cli import main

pytest.importorskip("uvicorn")


def test_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    assert "--host" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [
        ["--port", "70000"],
        ["--policy", "gpt"],
        ["--workers", "0"],
        ["--seed", "-1"],
        ["--bogus"],
        ["--host", "0.0.0.0"],  # beyond this machine without --allow-remote
        ["--host", "0.0.0.0", "--allow-remote"],  # every interface: no name to check a Host against
    ],
)
def test_usage_errors_exit_2(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_console_script_serves_the_page_and_warns_when_exposed() -> None:
    port = _free_port()
    cmd = [sys.executable, "-m", "steer_envs.ui", "--port", str(port), "--host", "0.0.0.0", "--allow-remote"]
    cmd += ["--allowed-host", "robot-pc.lan"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                with urlopen(f"http://127.0.0.1:{port}/", timeout=5) as page:
                    assert b"steer-ui" in page.read()
                break
            except (URLError, ConnectionError):
                assert proc.poll() is None, proc.communicate()
                assert time.monotonic() < deadline, "steer-ui did not start within 120 s"
                time.sleep(0.3)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert "warning: binding to 0.0.0.0" in err
