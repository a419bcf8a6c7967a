"""steer-ui's server over a real socket: sessions per connection, errors as messages, never a crash."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("websockets")

from websockets.sync.client import ClientConnection, connect

from steer_envs.ui.browser import RunningServer
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads

TIMEOUT = 60.0


@pytest.fixture(scope="module")
def server() -> Iterator[RunningServer]:
    with limit_threads(1, 1), RunningServer(UIConfig(workers=2, max_sessions=3)) as running:
        yield running


def ask(ws: ClientConnection, message: Any, until: str | None = None) -> dict[str, Any]:
    """Send ``message`` (a dict or raw text) and return the first reply of type ``until`` (or the first reply)."""
    ws.send(message if isinstance(message, str) else json.dumps(message))
    while True:
        reply: dict[str, Any] = json.loads(ws.recv(timeout=TIMEOUT))
        if until is None or reply["type"] in (until, "error"):
            return reply


def test_a_session_round_trip(server: RunningServer) -> None:
    with connect(server.ws_url) as ws:
        ready = ask(ws, {"type": "hello"})
        assert ready["type"] == "ready" and ready["width"] == 384 and ready["image"].startswith("data:image/png")
        agent = ready["agent"]
        ask(ws, {"type": "configure", "sampler": "GD", "batch": 4}, until="settings")
        sketch = [agent, [agent[0], agent[1] - 40.0], [agent[0] + 30.0, agent[1] - 40.0]]
        plans = ask(ws, {"type": "steer", "kind": "sketch", "points": sketch}, until="plans")
        assert plans["type"] == "plans", plans
        assert len(plans["plans"]) == 4 and len(plans["plans"][0]) == 63 and plans["sampler"] == "GD"
        assert len(plans["interaction"]) == 64 and {"network_ms", "sampler_ms", "server_ms"} <= set(plans["timings"])
        frame = ask(ws, {"type": "step"}, until="frame")
        assert frame["why"] == "step" and len(frame["executed"]) == 63 and frame["agent"] != agent
        nudged = ask(ws, {"type": "nudge", "to": [200.0, 150.0]}, until="frame")
        assert nudged["why"] == "nudge"
        reset = ask(ws, {"type": "reset", "seed": 5}, until="frame")
        assert reset["seed"] == 5


def test_bad_messages_get_errors_and_the_connection_stays(server: RunningServer) -> None:
    bad: list[Any] = [
        "{bad json",
        {"type": "launch"},
        {"type": "steer", "kind": "sketch", "points": [[1e9, 1.0], [2.0, 2.0]]},
        {"type": "steer", "kind": "sketch", "points": [[1.0, 1.0]] * 5000},
        {"type": "steer", "kind": "sketch", "points": "abc"},
        {"type": "steer", "kind": "blob"},
        {"type": "configure", "sampler": "XX"},
        {"type": "configure", "batch": 10**6},
        {"type": "nudge", "to": [1.0]},
        {"type": "reset", "seed": -3},
        '{"type": "steer", "kind": "sketch", "points": [[NaN, 1], [2, 2]]}',
    ]
    with connect(server.ws_url) as ws:
        ask(ws, {"type": "hello"})
        for message in bad * 10:
            reply = ask(ws, message)
            assert reply["type"] == "error" and reply["message"], (message, reply)
        ws.send(b"binary")
        assert json.loads(ws.recv(timeout=TIMEOUT))["type"] == "error"
        assert ask(ws, {"type": "hello"})["type"] == "ready"  # still serving


def test_play_and_pause(server: RunningServer) -> None:
    with connect(server.ws_url) as ws:
        ask(ws, {"type": "hello"})
        ask(ws, {"type": "configure", "sampler": "RS", "batch": 2, "execute": 4}, until="settings")
        assert ask(ws, {"type": "play"}, until="playing")["playing"] is True
        assert json.loads(ws.recv(timeout=TIMEOUT))["type"] == "plans"
        assert json.loads(ws.recv(timeout=TIMEOUT))["type"] == "frame"
        ws.send(json.dumps({"type": "pause"}))
        for _ in range(10):
            reply = json.loads(ws.recv(timeout=TIMEOUT))
            if reply["type"] == "playing":
                assert reply["playing"] is False
                break
        else:
            pytest.fail("no 'playing: false' after pause")


def test_a_full_server_refuses_more_sessions(server: RunningServer) -> None:
    with connect(server.ws_url) as a, connect(server.ws_url) as b, connect(server.ws_url) as c:
        for ws in (a, b, c):
            ask(ws, {"type": "hello"})
        with connect(server.ws_url) as d:
            reply = json.loads(d.recv(timeout=TIMEOUT))
            assert reply["type"] == "error" and "full" in reply["message"]
    for _ in range(50):  # closed tabs free their place (once the server has seen them close)
        with connect(server.ws_url) as e:
            if ask(e, {"type": "hello"})["type"] == "ready":
                return
        time.sleep(0.1)
    pytest.fail("closed connections did not free their places")


def test_page_and_health(server: RunningServer) -> None:
    from urllib.request import urlopen

    with urlopen(server.url, timeout=TIMEOUT) as page:
        assert b"steer-ui" in page.read()
    with urlopen(server.url + "/api/health", timeout=TIMEOUT) as health:
        status = json.loads(health.read())
    assert status["status"] == "ok" and status["warm_up_ms"] > 0  # a steering call ran before serving


def test_foreign_origins_are_refused_and_the_own_page_is_accepted(server: RunningServer) -> None:
    from websockets.exceptions import InvalidStatus

    host = server.url.removeprefix("http://")
    for origin in ("http://evil.example.com", "null", f"http://{host}.evil.example.com"):
        with pytest.raises(InvalidStatus) as refused, connect(server.ws_url, origin=origin):  # type: ignore[arg-type]
            pass
        assert refused.value.response.status_code == 403, origin
    with connect(server.ws_url, origin=f"http://{host}") as ws:  # type: ignore[arg-type]
        assert ask(ws, {"type": "hello"})["type"] == "ready"


def test_a_foreign_host_header_is_refused(server: RunningServer) -> None:
    """DNS rebinding: a page of evil.example.com whose name now points at 127.0.0.1."""
    import http.client

    from websockets.exceptions import InvalidStatus

    for path in ("/", "/api/health"):
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=TIMEOUT)
        conn.request("GET", path, headers={"Host": f"evil.example.com:{server.port}"})
        assert conn.getresponse().status == 400, path
        conn.close()
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=TIMEOUT)
    conn.request("GET", "/api/health", headers={"Host": f"localhost:{server.port}"})
    assert conn.getresponse().status == 200
    conn.close()
    with (
        pytest.raises(InvalidStatus) as refused,
        connect(server.ws_url, additional_headers={"Host": "evil.example.com"}),
    ):
        pass
    assert refused.value.response.status_code == 400


def test_configure_null_means_the_default(server: RunningServer) -> None:
    with connect(server.ws_url) as ws:
        ask(ws, {"type": "hello"})
        changed = ask(ws, {"type": "configure", "sampler": "GD", "batch": 4}, until="settings")
        assert changed["settings"]["sampler"] == "GD" and changed["settings"]["batch"] == 4
        back = ask(ws, {"type": "configure", "sampler": None, "batch": None}, until="settings")
        assert back["type"] == "settings", back
        assert back["settings"]["sampler"] == "SS" and back["settings"]["batch"] == 32  # Maze2D's defaults


def test_play_stops_when_the_episode_ends_and_reset_starts_afresh(server: RunningServer) -> None:
    with connect(server.ws_url) as ws:
        ask(ws, {"type": "hello"})
        ask(ws, {"type": "configure", "sampler": "RS", "batch": 2}, until="settings")  # a whole plan per tick
        assert ask(ws, {"type": "play"}, until="playing")["playing"] is True
        ended = False
        for _ in range(2000):
            reply = json.loads(ws.recv(timeout=TIMEOUT))
            assert reply["type"] != "error", reply
            ended = ended or (reply["type"] == "frame" and reply["done"])
            if reply["type"] == "playing":
                assert reply["playing"] is False and ended
                break
        else:
            pytest.fail("play did not stop at the end of the episode")
        # Play on an ended episode: refused, and the page is told that play stopped (its button reads Play)
        assert ask(ws, {"type": "play"}, until="playing")["playing"] is True
        replies = [json.loads(ws.recv(timeout=TIMEOUT)) for _ in range(2)]
        assert {r["type"] for r in replies} == {"playing", "error"}, replies
        assert next(r for r in replies if r["type"] == "playing")["playing"] is False
        frame = ask(ws, {"type": "reset", "seed": 1}, until="frame")
        assert frame["done"] is False
        assert ask(ws, {"type": "step"}, until="frame")["type"] == "frame"  # steering works again
