"""The arm push domains without a browser: ArmScoop's spoon dragged in the camera's plane, a refused push."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

pytest.importorskip("robosuite")

from steer_envs.envs.robosuite.arm_scoop import BOWL_X, SOUP_SURFACE, SOUP_Y
from steer_envs.ui.push_session import PushSession
from steer_envs.ui.views import PlaneView, SessionError
from steer_envs.utils.threads import limit_threads


@pytest.fixture(scope="module")
def arm() -> Iterator[PushSession]:
    with limit_threads(1, 1):
        session = PushSession("arm-scoop", seed=0)
    yield session
    session.close()


def test_the_drag_plane_round_trip(arm: PushSession) -> None:
    view = arm.pixels
    assert isinstance(view, PlaneView) and (view.width, view.height) == (320, 320)
    points = np.array([[BOWL_X, SOUP_Y, SOUP_SURFACE], [BOWL_X, 0.2, 1.1], [BOWL_X, -0.3, 0.9]])
    pixels = view.to_pixels(points)
    assert np.all((pixels > 0) & (pixels < 320))
    np.testing.assert_allclose(view.to_world(pixels, BOWL_X), points, atol=1e-9)
    assert view.to_pixels(points[0])[0] < view.to_pixels(points[1])[0]  # +y is to the right in the front camera
    with pytest.raises(SessionError, match="behind the camera"):
        view.to_world([[160.0, 160.0]], 50.0)
    with pytest.raises(SessionError, match="world points"):
        view.to_pixels([[1.0, 2.0]])


def test_pushes_replan_and_a_refused_push_moves_nothing(arm: PushSession) -> None:
    with limit_threads(1, 1):
        arm.reset(seed=0)
        arm.execute()
        assert arm.state.shape == (3,) and abs(arm.state[0] - BOWL_X) < 0.02
        soup = arm.pixels.to_pixels([arm.state[0], SOUP_Y, SOUP_SURFACE - 0.03])  # on the plane through the spoon
        arm.push_pixel(*soup)  # lands on the drag plane through the spoon
        panel = dict(arm.panel())
        assert panel["automaton mode"] == "b" and panel["last mode change"].startswith("push: a → b")
        np.testing.assert_allclose(arm.state[1:], [SOUP_Y, SOUP_SURFACE - 0.03], atol=2e-3)
        overlays = arm.overlays()
        assert len(overlays["flow"]) == 225 and len(overlays["attractor"]) == 1

        base = arm.env.unwrapped
        base.perturb(to=np.array([-0.3, 0.95, 1.2]))  # the spoon tipped far over: the far corner is out of reach
        before, info = arm.state, arm.info
        assert arm.push([BOWL_X, -0.38, 0.95]) == info
        assert arm.notice.startswith("push refused: ArmScoopEnv.perturb: `to`")
        np.testing.assert_array_equal(arm.state, before)
        assert arm.execute().executed.shape[1] == 3 and arm.notice == ""  # the session goes on


def test_a_cut_is_drawn_where_it_crosses_the_drawn_plane(arm: PushSession) -> None:
    controller = arm.controller
    view = arm.pixels
    line = controller._cut_line(view, np.array([0.0, 0.9, 0.0]), np.array([1.0, 0.0, 0.0]))  # y = 0, any z, pitch
    assert len(line) == 2
    world = view.to_world(np.asarray(line), BOWL_X)
    np.testing.assert_allclose(world[:, 1], 0.0, atol=1e-3)
    assert controller._cut_line(view, np.zeros(3), np.array([0.0, 0.0, 1.0])) == []  # parallel to the drawn plane


def test_the_arm_glide_setup_is_checked() -> None:
    from steer_envs.ui.arm_glide import ArmGlideSetup, mode_runs, quick_arm_glide_setup

    assert quick_arm_glide_setup().key() != ArmGlideSetup().key()
    assert ArmGlideSetup(bc_steps=10).key() == ArmGlideSetup().key()  # the classifier does not depend on the BC
    for bad, match in (({"task": "square"}, "task"), ({"replay_demos": 21}, "replay_demos"), ({"epochs": 0}, "epochs")):
        with pytest.raises(ValueError, match=match):
            ArmGlideSetup(**bad)  # type: ignore[arg-type]
    assert mode_runs([], ("reach",)) == "–"
