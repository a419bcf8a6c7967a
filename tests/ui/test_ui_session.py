"""Session: the steering loop without a browser (shipped DP, Maze2D-Large)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from steer_envs.core.interaction import Point, Sketch
from steer_envs.core.metrics import sketch_distances
from steer_envs.ui.session import DOMAINS, Session, SteerSettings
from steer_envs.ui.views import MAX_INPUT_POINTS, PixelMap, SessionError, resample_by_arclength
from steer_envs.utils.threads import limit_threads


@pytest.fixture(scope="module")
def session() -> Iterator[Session]:
    with limit_threads(1, 1):
        s = Session(seed=3, settings=SteerSettings(batch=8))
    yield s
    s.close()


def _sketch_up(session: Session) -> np.ndarray:
    start = session.state
    # one cell "up" in the image is x - 1 (Maze2D: x = row); stay inside the maze
    return start + np.array([[0.0, 0.0], [0.0, 1.0], [0.0, 2.0]])


def test_pixel_map_round_trip(session: Session) -> None:
    pixels = np.array([[0.0, 0.0], [10.5, 3.25], [383.0, 287.0]])
    assert np.allclose(session.pixels.to_pixels(session.pixels.to_world(pixels)), pixels)
    # Maze2D's own mapping: x = row (v), y = column (u)
    maze = session.env.unwrapped
    assert np.allclose(session.pixels.to_world(pixels[1]), maze.pixel_to_xy(10.5, 3.25))  # type: ignore[attr-defined]


def test_steer_sample_execute_and_nudge(session: Session) -> None:
    session.reset(seed=3)
    with limit_threads(1, 1):
        session.configure(sampler="SS", batch=8)
        sketch = Sketch(_sketch_up(session))
        steered = session.steer(sketch)
        assert steered.plans.shape == (8, 63, 2) and steered.collides is not None and steered.collides.shape == (8,)
        assert steered.timings["network_evals"] == 40 and steered.timings["network_ms"] > 0
        assert steered.timings["network_ms"] <= steered.timings["total_ms"] + 1e-6
        session.configure(sampler="RS")
        unsteered = session.steer(sketch)
        ss = sketch_distances(steered.plans, sketch).mean()
        rs = sketch_distances(unsteered.plans, sketch).mean()
        assert ss < rs, (ss, rs)
        before = session.state
        step = session.execute()
        assert len(step.executed) == 63 and session.last is None
        assert not np.allclose(session.state, before)
        target = session.pixels.to_world([session.pixels.width / 2 + 3, session.pixels.height / 2])
        session.nudge_pixel(session.pixels.width / 2 + 3, session.pixels.height / 2)
        assert np.linalg.norm(session.state - target) < 0.6  # projected into free space
        point = session.steer_pixels("point", [[100.0, 100.0]])
        assert isinstance(point.interaction, Point) and np.isfinite(point.costs).all()


def test_reset_is_reproducible(session: Session) -> None:
    with limit_threads(1, 1):
        session.configure(sampler="GD", batch=4)
        session.reset(seed=11)
        a = session.steer(Sketch(_sketch_up(session))).plans
        session.reset(seed=11)
        b = session.steer(Sketch(_sketch_up(session))).plans
    assert np.array_equal(a, b)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda s: s.steer_pixels("sketch", [[-5.0, 3.0], [10.0, 10.0]]), ValueError, "inside the 384x288 image"),
        (lambda s: s.steer_pixels("sketch", [[5.0, float("nan")], [10.0, 10.0]]), ValueError, "finite"),
        (lambda s: s.steer_pixels("sketch", [[5.0, 5.0], [5.0, 5.0]]), SessionError, "non-zero length"),
        (lambda s: s.steer_pixels("point", [[5.0, 5.0], [6.0, 5.0]]), SessionError, "one \\[u, v\\] pair"),
        (lambda s: s.steer_pixels("scribble", [[5.0, 5.0]]), ValueError, "kind"),
        (lambda s: s.steer_pixels("sketch", np.ones((MAX_INPUT_POINTS + 1, 2))), SessionError, "at most"),
        (lambda s: s.steer_pixels("sketch", "12"), TypeError, "points"),
        (lambda s: s.configure(sampler="XX"), ValueError, "sampler"),
        (lambda s: s.configure(batch=0), ValueError, "batch"),
        (lambda s: s.configure(batch=True), TypeError, "batch"),
        (lambda s: s.configure(guide_ratio=float("inf")), ValueError, "guide_ratio"),
        (lambda s: s.configure(temperature=2), TypeError, "unknown knob"),
        (lambda s: s.nudge([1.0, 2.0, 3.0]), SessionError, "world point"),
        (lambda s: s.reset(seed=-1), ValueError, "seed"),
        (lambda s: s.steer("a sketch"), TypeError, "interaction"),
    ],
)
def test_bad_input_gets_a_clear_error(session: Session, call, error, match) -> None:  # type: ignore[no-untyped-def]
    session.reset(seed=0)
    before = session.settings
    with pytest.raises(error, match=match):
        call(session)
    assert session.settings == before  # a refused request changes nothing


def test_op_needs_a_sketch(session: Session) -> None:
    session.reset(seed=0)
    session.configure(sampler="OP")
    with pytest.raises(SessionError, match="OP"):
        session.steer(Point(session.state))
    session.configure(sampler="SS")


def test_act_refuses_diffusion_samplers() -> None:
    with limit_threads(1, 1):
        act = Session(policy="act", settings=SteerSettings(sampler="RS", batch=2))
    try:
        with pytest.raises(TypeError, match="DiffusionPolicyLike"):
            act.configure(sampler="SS")
        assert act.settings.sampler == "RS"
        assert act.steer(None).plans.shape[0] == 2
    finally:
        act.close()


def test_resample_by_arclength_spaces_points_evenly() -> None:
    drawn = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.3, 0.0], [3.0, 0.0], [3.0, 1.0]])
    out = resample_by_arclength(drawn, 5)
    steps = np.linalg.norm(np.diff(out, axis=0), axis=1)
    assert np.allclose(steps, 1.0) and np.allclose(out[0], drawn[0]) and np.allclose(out[-1], drawn[-1])


def test_pixel_map_refuses_envs_without_a_2d_view() -> None:
    class NoView:
        pass

    class Curved:
        def pixel_to_xy(self, u: float, v: float) -> np.ndarray:
            return np.array([u * u, v])

    with pytest.raises(SessionError, match="pixel_to_xy"):
        PixelMap.from_env(NoView(), 10, 10)
    with pytest.raises(SessionError, match="affine"):
        PixelMap.from_env(Curved(), 10, 10)


def test_settings_are_checked() -> None:
    assert SteerSettings(sampler="GD", guide_ratio=30).checked().make_sampler().guide_ratio == 30.0
    with pytest.raises(ValueError, match="mcmc_steps"):
        SteerSettings(mcmc_steps=0).checked()
    with pytest.raises(TypeError, match="use_clipped_model_output"):
        SteerSettings(use_clipped_model_output="yes").checked()  # type: ignore[arg-type]
    blockstack = DOMAINS["blockstack"].settings.checked().make_sampler()
    assert blockstack.name == "GD" and blockstack.use_clipped_model_output
    assert not SteerSettings(sampler="GD").checked().make_sampler().use_clipped_model_output


def test_blockstack_clicks_land_on_surfaces_and_skills_run() -> None:
    """The camera domain: a click on a cube is a 3D point on its top face; a plan runs as a whole skill."""
    with limit_threads(1, 1):
        arm = Session("blockstack", seed=100_000, settings=SteerSettings(sampler="GD", batch=2, guide_ratio=10.0))
    try:
        base = arm.env.unwrapped
        cube = base.cube_pos[0]  # type: ignore[attr-defined]
        pixel = arm.pixels.to_pixels(cube)
        on_top = arm.pixels.to_world([pixel])[0]
        assert np.linalg.norm(on_top[:2] - cube[:2]) < 0.03 and 0.0 < on_top[2] - cube[2] < 0.03
        assert np.allclose(arm.pixels.to_pixels(on_top), pixel, atol=1.0)
        assert arm.kinds == ("point", "sketch") and arm.dims == (0, 1, 2)
        with pytest.raises(SessionError, match="no nudges"):
            arm.nudge(on_top)
        with limit_threads(1, 1):
            outcome = arm.steer_pixels("point", [pixel])
            assert outcome.plans.shape == (2, 32, 4) and outcome.collides is None
            # what the server sends the page: the plans' positions in the camera (the gripper is not drawn)
            assert arm.pixels.to_pixels(outcome.plans).shape == (2, 32, 2)
            step = arm.execute()
        assert step.executed.shape[1] == 3 and len(step.executed) > 10  # the end effector's trail
        assert "skill" in step.info and arm.last is None
    finally:
        arm.close()
