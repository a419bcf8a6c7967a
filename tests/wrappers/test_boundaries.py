"""Every wrapper boundary refuses bad input clearly: arguments that can never work, silent coercion.

Example tests pin one case of each kind (they failed on the old code); the Hypothesis
properties throw random bad values at the same boundaries and accept only a clean
``TypeError``/``ValueError`` (``KeyError`` for a missing ``info["sensors"]``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stub_policies import StraightLine
from wrapper_bad_values import NOT_BOOL, NOT_REAL, SAMPLER_KNOBS, bad_vectors

import steer_envs  # noqa: F401
from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet, solve_cut
from steer_envs.baselines.lpv_ds.modulation import ModulatedPolicy, modulate
from steer_envs.core.interaction import Nudge, Point, Sketch
from steer_envs.core.validation import sensor_reading
from steer_envs.ltl import specs
from steer_envs.ltl.specs import for_env
from steer_envs.steering import (
    MAX_BATCH,
    BiasedInitialization,
    GuidedDiffusion,
    OutputPerturbation,
    PostHocRanking,
    RandomSampling,
    StochasticSampling,
    make_sampler,
)
from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper, SteeringWrapper

torch = pytest.importorskip("torch")

CLEAN = (TypeError, ValueError)


_CACHE: dict[str, Any] = {}


def convex(**kwargs: Any) -> gym.Env:
    return gym.make("steer_envs/ConvexMode-v0", layout_seed=0, **kwargs)


def steering(sketch_points: int | None = None) -> SteeringWrapper:
    key = f"steer{sketch_points}"
    if key not in _CACHE:
        env = SteeringWrapper(convex(), StraightLine(), PostHocRanking(), batch=2, sketch_points=sketch_points)
        env.reset(seed=0)
        _CACHE[key] = env
    return _CACHE[key]


def ds_wrapper() -> DSModulationWrapper:
    if "ds" not in _CACHE:
        env = DSModulationWrapper(convex(), attractor=[0.0, 0.0])
        env.reset(seed=0)
        _CACHE["ds"] = env
    return _CACHE["ds"]


def ltl_wrapper() -> LTLReplanWrapper:
    if "ltl" not in _CACHE:
        env = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
        env.reset(seed=0)
        _CACHE["ltl"] = env
    return _CACHE["ltl"]


# ------------------------------------------------------------ SteeringWrapper: arguments
def test_steering_refuses_samplers_and_knobs_that_can_never_work() -> None:
    with pytest.raises(TypeError, match="DiffusionPolicyLike"):  # GD needs a denoiser: used to fail at every step
        SteeringWrapper(convex(), StraightLine(), GuidedDiffusion())
    with pytest.raises(TypeError, match="DiffusionPolicyLike"):
        SteeringWrapper(convex(), StraightLine(), PostHocRanking(), unsteered=StochasticSampling())
    with pytest.raises(ValueError, match="batch"):
        SteeringWrapper(convex(), StraightLine(), PostHocRanking(), batch=MAX_BATCH + 1)
    with pytest.raises(TypeError, match="batch"):
        SteeringWrapper(convex(), StraightLine(), PostHocRanking(), batch="32")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="sketch_points"):
        SteeringWrapper(convex(), StraightLine(), PostHocRanking(), sketch_points=6.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="sketch_points"):
        SteeringWrapper(convex(), StraightLine(), PostHocRanking(), sketch_points=10**9)


def test_sampler_knobs_are_checked_at_construction() -> None:
    with pytest.raises(TypeError, match="guide_ratio"):
        GuidedDiffusion(guide_ratio="20")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="guide_ratio"):
        GuidedDiffusion(guide_ratio=float("nan"))
    with pytest.raises(ValueError, match="mcmc_steps"):
        StochasticSampling(mcmc_steps=10**9)  # would run for ever
    with pytest.raises(TypeError, match="mcmc_steps"):
        StochasticSampling(mcmc_steps=4.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="init_std"):
        BiasedInitialization(init_std=1j)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="index"):
        OutputPerturbation(index="20")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="name"):
        make_sampler(3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="one of"):
        make_sampler("DDIM")
    gd_knobs = r"\['guide_ratio', 'min_guided_t', 'use_clipped_model_output'\]"
    with pytest.raises(TypeError, match=r"GuidedDiffusion \(GD\) takes " + gd_knobs):
        make_sampler("GD", mcmc_steps=4)
    with pytest.raises(TypeError, match="n"):
        RandomSampling()(StraightLine(), np.zeros(2), None, 2.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="n"):
        RandomSampling()(StraightLine(), np.zeros(2), None, MAX_BATCH + 1)


# ----------------------------------------------------------- SteeringWrapper: the action
def test_steering_action_is_an_interaction_or_a_real_flat_sketch() -> None:
    env = steering(sketch_points=3)
    flat = np.array([0.0, 0.0, 0.5, 0.5, 1.0, 1.0])
    assert isinstance(env.interaction(flat), Sketch)
    with pytest.raises(TypeError, match="real numbers"):  # used to parse the strings
        env.interaction([str(v) for v in flat])
    with pytest.raises(TypeError, match="real numbers"):  # used to drop the imaginary part
        env.interaction(flat + 1j)
    with pytest.raises(ValueError, match="finite"):
        env.interaction(np.where(np.arange(6) == 2, np.nan, flat))
    with pytest.raises(TypeError, match="real numbers"):
        env.interaction([True] * 6)
    grad = torch.tensor(flat, requires_grad=True)  # used to crash in .numpy()
    assert env.interaction(grad) == env.interaction(flat)
    plain = steering()
    with pytest.raises(TypeError, match="Point, Sketch, Nudge or None"):
        plain.interaction(flat)


def test_steering_refuses_interaction_kinds_the_env_does_not_declare() -> None:
    env = convex()
    env.unwrapped.interaction_kinds = ("sketch",)  # type: ignore[misc]
    wrapped = SteeringWrapper(env, StraightLine(), OutputPerturbation(), batch=2)
    wrapped.reset(seed=0)
    assert wrapped.interaction(Sketch([[0, 0], [1, 1]])) is not None
    with pytest.raises(ValueError, match=r"kinds \['sketch'\], got a point"):
        wrapped.interaction(Point([1.0, 1.0]))
    with pytest.raises(ValueError, match="nudge"):
        wrapped.interaction(Nudge([[1.0, 1.0]]))


@settings(max_examples=60, deadline=None)
@given(st.one_of(bad_vectors(6), NOT_REAL).filter(lambda a: a is not None))  # None: unsteered
def test_property_steering_flat_sketch_refuses_bad_actions(action: object) -> None:
    with pytest.raises(CLEAN):
        steering(sketch_points=3).interaction(action)


@settings(max_examples=40, deadline=None)
@given(st.one_of(bad_vectors(2), NOT_REAL, st.integers(), st.floats()).filter(lambda a: a is not None))
def test_property_steering_plain_refuses_anything_but_interactions(action: object) -> None:
    with pytest.raises(CLEAN):
        steering().step(action)


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(list(SAMPLER_KNOBS)),
    st.one_of(NOT_REAL, st.integers(-(10**12), -1), st.integers(10**7, 10**12), st.floats()),
)
def test_property_sampler_knobs(knob: str, value: object) -> None:
    cls = SAMPLER_KNOBS[knob]
    try:
        sampler = cls(**{knob: value})
    except CLEAN:
        return
    # what is accepted is a documented value: a finite real/int within its range
    got = getattr(sampler, knob)
    assert type(got) in (int, float) and np.isfinite(got)
    assert not isinstance(value, (str, bool, complex)) and value is not None


# -------------------------------------------------------------- DSModulationWrapper
def test_ds_modulation_refuses_attractors_and_modes_that_can_never_learn_a_cut() -> None:
    with pytest.raises(ValueError, match=r"state's shape \(2,\)"):  # used to never learn a cut
        DSModulationWrapper(convex(), attractor=[0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="home_mode"):  # ConvexMode has modes 0 (inside) and 1 (outside)
        DSModulationWrapper(convex(), attractor=[0.0, 0.0], home_mode=3)
    with pytest.raises(ValueError, match="mode index"):
        DSModulationWrapper(convex(), attractor={5: [0.0, 0.0]})
    with pytest.raises(TypeError, match="mode index"):
        DSModulationWrapper(convex(), attractor={"0": [0.0, 0.0]})  # type: ignore[dict-item]
    with pytest.raises(ValueError, match="dimension 3"):
        DSModulationWrapper(convex(), attractor=[0.0, 0.0], cuts={0: CutSet(np.zeros(3))})
    with pytest.raises(TypeError, match="learn"):
        DSModulationWrapper(convex(), attractor=[0.0, 0.0], learn="no")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="margin"):
        DSModulationWrapper(convex(), attractor=[0.0, 0.0], margin="0.4")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="at least one mode"):
        DSModulationWrapper(convex(), attractor={})


def test_ds_modulation_step_takes_real_velocities_only() -> None:
    env = DSModulationWrapper(convex(), attractor=[0.0, 0.0])
    env.reset(seed=0)
    with pytest.raises(TypeError, match="action"):  # used to parse the strings
        env.step(["1", "2"])
    with pytest.raises(TypeError, match="action"):  # used to drop the imaginary part
        env.step(np.array([1.0 + 2j, 0.0]))
    with pytest.raises(ValueError, match="finite"):
        env.step([np.nan, 0.0])
    with pytest.raises(ValueError, match="shape"):
        env.step([1.0, 2.0, 3.0])
    a, b = DSModulationWrapper(convex(), attractor=[0.0, 0.0]), DSModulationWrapper(convex(), attractor=[0.0, 0.0])
    a.reset(seed=1), b.reset(seed=1)
    v = [0.3, -0.2]
    out_np = a.step(np.asarray(v))[0]
    out_grad = b.step(torch.tensor(v, requires_grad=True))[0]  # used to crash in .numpy()
    np.testing.assert_array_equal(out_np, out_grad)


def test_cut_functions_refuse_strings_and_complex() -> None:
    with pytest.raises(TypeError, match="last_in_mode"):
        solve_cut(["3", "0"], [3.1, 0.0], [-3.0, 0.0], [0.0, 0.0])
    with pytest.raises(TypeError, match="point"):
        Cut(np.array([1.0 + 1j, 0.0]), np.array([1.0, 0.0]))
    cuts = CutSet(np.zeros(2), [Cut(np.array([2.0, 0.0]), np.array([1.0, 0.0]))])
    with pytest.raises(TypeError, match="velocity"):
        modulate(np.zeros((1, 2)), [["1", "0"]], cuts)
    with pytest.raises(TypeError, match="max_speed"):
        modulate(np.zeros((1, 2)), np.ones((1, 2)), cuts, max_speed="20")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_speed"):
        ModulatedPolicy(lambda x: x, cuts, max_speed=-1.0)
    with pytest.raises(ValueError, match="visited"):
        solve_cut([3.0, 0.0], [3.1, 0.0], [-3.0, 0.0], [0.0, 0.0], visited=np.zeros(3))


@settings(max_examples=80, deadline=None)
@given(bad_vectors(2))
def test_property_ds_modulation_step_refuses_bad_velocities(action: object) -> None:
    env = ds_wrapper()
    before = env.unwrapped.state
    with pytest.raises(CLEAN):
        env.step(action)
    np.testing.assert_array_equal(env.unwrapped.state, before)  # nothing moved


@settings(max_examples=60, deadline=None)
@given(bad_vectors(2), st.one_of(st.integers(-3, 3), NOT_REAL))
def test_property_ds_modulation_constructor(attractor: object, mode: object) -> None:
    with pytest.raises(CLEAN):
        DSModulationWrapper(convex(), attractor=attractor)
    try:
        DSModulationWrapper(convex(), attractor=[0.0, 0.0], home_mode=mode)  # type: ignore[arg-type]
    except CLEAN:
        return
    assert mode is None or (mode in (0, 1) and type(mode) is int)  # the default, or a mode of ConvexMode


# ------------------------------------------------------------------ LTLReplanWrapper
def test_ltl_readings_must_be_real_bools() -> None:
    env = ltl_wrapper()
    reading = {"r": False, "s": False, "t": False}
    assert env.sync({"sensors": reading})["ltl_mode"] == "a"
    with pytest.raises(TypeError, match=r"info\['sensors'\]\['r'\] must be a bool, got str 'False'"):
        env.sync({"sensors": {**reading, "r": "False"}})  # bool("False") is True
    with pytest.raises(TypeError, match="must be a bool"):
        env.sync({"sensors": {**reading, "s": float("nan")}})  # bool(nan) is True
    with pytest.raises(TypeError, match="must be a bool"):
        env.sync({"sensors": {**reading, "t": 1}})
    with pytest.raises(ValueError, match=r"missing \['t'\]"):
        env.sync({"sensors": {"r": False, "s": False}})
    with pytest.raises(ValueError, match=r"unknown \['u'\]"):
        env.sync({"sensors": {**reading, "u": False}})
    with pytest.raises(TypeError, match="mapping"):
        env.sync({"sensors": ["r"]})
    assert env.sync({"sensors": {"r": np.bool_(True), "s": False, "t": False}})["ltl_mode"] == "b"
    env.reset(seed=0)


def test_ltl_wrapper_refuses_specs_and_tasks_that_can_never_match() -> None:
    with pytest.raises(ValueError, match="variant"):
        LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), "phi_cb")  # a Cooking spec name
    cooking = gym.make("steer_envs/Cooking-v0").unwrapped.task
    with pytest.raises(ValueError, match="sensors"):
        LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), specs.cooking("phi_cb"), task=cooking)
    with pytest.raises(ValueError, match="APs"):  # a spec over another task's APs
        LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), for_env("steer_envs/Cooking-v0"))


@settings(max_examples=80, deadline=None)
@given(st.sampled_from(["r", "s", "t"]), NOT_BOOL)
def test_property_ltl_sensor_values_are_refused_unless_bool(ap: str, value: object) -> None:
    reading: dict[str, object] = {"r": False, "s": False, "t": False, ap: value}
    with pytest.raises(TypeError):
        sensor_reading({"sensors": reading}, ("r", "s", "t"), owner="test")
    with pytest.raises(TypeError):
        ltl_wrapper().sync({"sensors": reading})


@settings(max_examples=40, deadline=None)
@given(
    st.one_of(
        NOT_REAL,
        st.lists(st.text(max_size=2), max_size=3),
        st.dictionaries(st.sampled_from(["r", "s", "t", "u", ""]), st.booleans()).filter(
            lambda d: set(d) != set("rst")
        ),
    )
)
def test_property_ltl_readings_of_the_wrong_shape(sensors: object) -> None:
    with pytest.raises((TypeError, ValueError, KeyError)):
        ltl_wrapper().sync({"sensors": sensors})
