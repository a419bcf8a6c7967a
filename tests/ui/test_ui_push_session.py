"""The domain registry, and push sessions (a controller a person pushes) without a browser and over a socket."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest

from steer_envs.ui.domains import DOMAINS, INTERACTIONS, Domain, Overlay
from steer_envs.ui.push_session import PushSession
from steer_envs.ui.session import Session
from steer_envs.ui.views import PixelMap, SessionError
from steer_envs.utils.threads import limit_threads


@pytest.fixture(scope="module")
def scoop() -> Iterator[PushSession]:
    with limit_threads(1, 1):
        session = PushSession("soup-scoop", seed=1)
    yield session
    session.close()


def test_every_domain_declares_what_the_page_builds() -> None:
    for name, domain in DOMAINS.items():
        decl = domain.declaration(name)
        assert decl["name"] == name and decl["title"] and decl["interactions"] and decl["overlays"]
        for interaction in decl["interactions"]:
            assert interaction["message"] in ("steer", "nudge", "push") and interaction["hint"]
        assert decl["steering"] == (domain.session == "steer")
    assert DOMAINS["maze2d"].declaration("maze2d", ("point", "nudge"))["interactions"][0]["kind"] == "point"
    assert set(INTERACTIONS) == {"sketch", "point", "nudge", "push"}


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"session": "push"}, "controller"),
        ({"session": "steer", "policies": ()}, "policy kinds"),
        ({"interactions": ("wave",)}, "interactions"),
        ({"overlays": (Overlay("x", "hologram"),)}, "overlay kind"),
        ({"view": "fisheye"}, "view"),
    ],
)
def test_a_bad_declaration_is_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Domain("steer_envs/SoupScoop-v0", {}, **{"policies": ("dp",), **kwargs})  # type: ignore[arg-type]


def test_sessions_refuse_the_other_kind_of_domain() -> None:
    with pytest.raises(SessionError, match="PushSession"):
        Session("soup-scoop")
    with pytest.raises(SessionError, match="Session"):
        PushSession("maze2d")
    with pytest.raises(ValueError, match="domain"):
        PushSession("pinball")


def test_box_view_round_trip() -> None:
    view = PixelMap.from_box([-8.0, -8.0], [8.0, 8.0], 256, 256)
    pixels = np.array([[0.0, 0.0], [10.5, 200.25], [256.0, 256.0]])
    assert np.allclose(view.to_pixels(view.to_world(pixels)), pixels)
    assert np.allclose(view.to_world([[256.0, 0.0]]), [[8.0, 8.0]])
    with pytest.raises(SessionError, match="low < high"):
        PixelMap.from_box([0.0, 0.0], [0.0, 1.0], 10, 10)


def test_push_the_spoon_the_automaton_replans_and_ltl_ds_recovers(scoop: PushSession) -> None:
    with limit_threads(1, 1):
        scoop.reset(seed=1)
        assert scoop.execute().executed.shape == (21, 2) and scoop.steps == 20
        overlays = scoop.overlays(full=True)
        assert len(overlays["flow"]) == 225 and len(overlays["attractor"]) == 1
        scoop.push([-2.0, -6.0])  # into the soup: a -> b
        scoop.push([4.0, -2.0])  # up the pink lane with soup: b -> c
        scoop.push([-4.0, 2.0])  # out of the lane: the soup spills, c -> a
        panel = dict(scoop.panel())
        assert panel["automaton mode"] == "a" and panel["plan"] == "a → b → c → d"
        assert panel["last mode change"].startswith("push: c → a (undid a mode; replanned")
        assert panel["replans (pushes, failures)"] == "3"
        scoop.configure(execute=500)
        while not scoop.done:
            scoop.execute()
        assert scoop.info["success"] and dict(scoop.panel())["automaton mode"] == "d"
        with pytest.raises(SessionError, match="reset"):
            scoop.push([0.0, 0.0])


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda s: s.push([1.0, 2.0, 3.0]), SessionError, "2 numbers"),
        (lambda s: s.push([float("nan"), 1.0]), ValueError, "finite"),
        (lambda s: s.push_pixel(-1.0, 5.0), SessionError, "inside the 256x256 image"),
        (lambda s: s.configure(sampler="SS"), TypeError, "one knob"),
        (lambda s: s.configure(execute=0), ValueError, "execute"),
        (lambda s: s.reset(seed=-1), ValueError, "seed"),
    ],
)
def test_bad_input_gets_a_clear_error(scoop: PushSession, call, error, match) -> None:  # type: ignore[no-untyped-def]
    scoop.reset(seed=1)
    before = (scoop.state, scoop.settings)
    with pytest.raises(error, match=match):
        call(scoop)
    assert np.array_equal(scoop.state, before[0]) and scoop.settings == before[1]


def test_a_push_domain_over_the_socket() -> None:
    pytest.importorskip("fastapi")
    from websockets.sync.client import connect

    from steer_envs.ui.browser import RunningServer
    from steer_envs.ui.server import UIConfig

    def ask(ws, message, until):  # type: ignore[no-untyped-def]
        ws.send(json.dumps(message))
        while True:
            reply = json.loads(ws.recv(timeout=60))
            if reply["type"] in (until, "error"):
                return reply

    with limit_threads(1, 1), RunningServer(UIConfig(domain="soup-scoop", seed=1, workers=1)) as server:
        with connect(server.ws_url) as ws:
            ready = ask(ws, {"type": "hello"}, "ready")
            assert ready["declaration"]["interactions"][0]["kind"] == "push" and ready["samplers"] == []
            assert {"flow", "cuts", "attractor"} <= set(ready["overlays"]) and ready["panel"][0][0] == "automaton mode"
            for refused in ({"type": "steer", "kind": "point", "points": [[5, 5]]}, {"type": "nudge", "to": [5, 5]}):
                assert ask(ws, refused, "frame")["type"] == "error"
            pushed = ask(ws, {"type": "push", "to": [96.0, 224.0]}, "frame")  # (-2, -6): into the soup
            assert pushed["why"] == "push" and dict(pushed["panel"])["automaton mode"] == "b"
            step = ask(ws, {"type": "step"}, "frame")
            assert step["steps"] == 20 and len(step["executed"]) == 21 and "mode_map" not in step["overlays"]
            assert ask(ws, {"type": "configure", "execute": 5}, "settings")["settings"] == {"execute": 5}
            assert ask(ws, {"type": "play"}, "playing")["playing"] is True
            assert json.loads(ws.recv(timeout=60))["type"] == "frame"  # a tick: no plans, a frame
