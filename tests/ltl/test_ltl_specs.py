"""The thesis specs as data, their attachment to envs, and the translation benchmark."""

from __future__ import annotations

import gymnasium as gym
import pytest

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.ltl import specs as S
from steer_envs.ltl.replanner import TaskAutomaton


def test_all_specs_are_named_and_distinct() -> None:
    names = set(S.all_specs())
    assert names == {
        "soup_scoop_public",
        "soup_scoop_thesis",
        "phi_cb",
        "phi_bc",
        "phi_c",
        "phi_cc",
        "color_tracing_a",
        "color_tracing_b",
        "color_tracing_c",
    }
    # the cooking variants share every part but phi_s_t (thesis: "edit the phi_s_t portion")
    cb, bc = S.cooking("phi_cb"), S.cooking("phi_bc")
    assert (cb.env_init, cb.env_safety, cb.sys_init, cb.sys_liveness) == (
        bc.env_init,
        bc.env_safety,
        bc.sys_init,
        bc.sys_liveness,
    )
    assert cb.sys_safety != bc.sys_safety


def test_for_env_by_id_and_by_env() -> None:
    assert S.for_env("steer_envs/SoupScoop-v0").name == "soup_scoop_public"
    assert S.for_env("SoupScoop-v0", "thesis").name == "soup_scoop_thesis"
    assert S.for_env("steer_envs/Cooking-v0").name == "phi_cb"
    assert S.for_env("Cooking-v0", "phi_cc").name == "phi_cc"
    assert S.variants("Cooking-v0") == ("phi_cb", "phi_bc", "phi_c", "phi_cc")
    env = gym.make("steer_envs/SoupScoop-v0", sensor_convention="thesis")
    assert S.for_env(env).name == "soup_scoop_thesis"  # follows the env's sensor convention
    env.close()
    with pytest.raises(ValueError, match="no LTL spec"):
        S.for_env("steer_envs/PolygonNav-3Mode-v0")
    with pytest.raises(ValueError, match="variant"):
        S.for_env("Cooking-v0", "phi_x")
    with pytest.raises(ValueError, match="convention"):
        S.soup_scoop("other")
    with pytest.raises(ValueError, match="variant"):
        S.color_tracing("d")


def test_specs_agree_with_the_env_modules() -> None:
    from steer_envs.envs.cooking import COOKING_TASK, MODE_AP_FORMULAS
    from steer_envs.envs.soup_scoop import SOUP_TASK

    assert dict(MODE_AP_FORMULAS) == dict(S.COOKING_MODE_FORMULAS)
    assert COOKING_TASK.sensors == S.COOKING_SENSORS
    # the soup env's transition structure is the automaton's, under both sensor conventions
    for convention in ("public", "thesis"):
        aut = TaskAutomaton(SOUP_TASK, S.soup_scoop(convention))
        assert aut.mode_edges() == SOUP_TASK.transitions
        for node in aut.nodes:  # the env's labelling and the spec's agree on every node
            assert SOUP_TASK.mode_of(node.sensors) == node.mode


def test_color_tracing_task() -> None:
    task = S.COLOR_TRACING_TASK
    assert task.modes == S.COLOR_MODES and task.sensors == S.COLOR_SENSORS
    assert task.shortest_plan("yellow") == ["yellow", "blue", "green", "orange", "pink", "red"]


def test_benchmark_translation_times_every_spec() -> None:
    timings = S.benchmark_translation(repeats=1)
    assert set(timings) == set(S.all_specs())
    assert all(t > 0 for t in timings.values())
    with pytest.raises(ValueError, match="repeats"):
        S.benchmark_translation(repeats=0)
