"""Parsing recorded LLM plans (thesis appendix format) into TaskSpecs and feasibility matrices."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from steer_envs.baselines.glide.llm_plan import (
    LLMProvider,
    RecordedProvider,
    build_prompt,
    parse_plan_response,
    request_plan,
)
from steer_envs.envs.polygon_nav import polygon_nav_task

FIXTURES = Path(__file__).parent / "fixtures"


def _fixture(name: str) -> str:
    return (FIXTURES / f"glide_llm_{name}.txt").read_text(encoding="utf-8")


def test_can_response_from_the_thesis_parses() -> None:
    plan = parse_plan_response(_fixture("can"))
    assert [s.id for s in plan.steps] == [1, 2, 3, 4]
    assert plan.steps[1].desc == "Close gripper to grasp the can"
    assert plan.feasibility[(1, 2)] is True and plan.feasibility[(1, 3)] is False
    assert plan.feasibility[(2, 4)] is True  # as the LLM answered
    assert plan.features == (
        "can_to_robot0_eef_pos",
        "can_to_robot0_eef_quat",
        "robot0_eef_pos",
        "robot0_eef_quat",
        "gripper_state",
    )
    assert plan.goals == {
        1: "can_to_robot0_eef_pos",
        2: "can_to_robot0_eef_pos",
        3: "robot0_eef_pos",
        4: "robot0_eef_pos",
    }
    task = plan.task_spec("can")
    assert task.num_modes == 4 and task.initial == task.modes[0] and task.goal == (task.modes[-1],)
    feas = plan.feasibility_matrix()
    assert feas[0, 2] == -1 and feas[0, 3] == -1  # 1 -> 4 goes 1 -> 2 -> 4: one mode skipped
    assert np.all(np.diag(feas) == 0) and feas[0, 1] == 0


def test_square_response_uses_goals_tag_and_gives_the_chain_matrix() -> None:
    plan = parse_plan_response(_fixture("square"))
    assert plan.num_modes == 4 and len(plan.goals or {}) == 4
    np.testing.assert_array_equal(
        plan.feasibility_matrix("forward"), [[0, 0, -1, -2], [0, 0, 0, -1], [0, 0, 0, 0], [0, 0, 0, 0]]
    )
    np.testing.assert_array_equal(plan.feasibility_matrix()[3], [-2, -1, 0, 0])  # undirected shortest path


def test_lift_response_and_directed_reading() -> None:
    plan = parse_plan_response(_fixture("lift"))
    assert plan.num_modes == 3
    directed = plan.task_spec(symmetric=False)
    assert directed.is_allowed(0, 1) and not directed.is_allowed(1, 0)
    assert plan.task_spec().is_allowed(1, 0)


def test_polygon_nav_plan_matches_the_env_chain() -> None:
    plan = parse_plan_response(_fixture("polygon_nav_4mode_handwritten"))
    env_task = polygon_nav_task(4)
    np.testing.assert_array_equal(plan.feasibility_matrix("forward"), env_task.feasibility_matrix("forward"))
    assert plan.features == ("agent_pos",)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("no tags here", "no <plan>"),
        ("<plan>steps = [{'id': 1, 'desc': 'a'}, {'id': 2, 'desc': 'b'}]</plan>", "no <feasibility>"),
        ("<plan>steps = [{'id': 1, 'desc': 'a'}]</plan><feasibility>{}</feasibility>", "at least two"),
        ("<plan>steps = [1, 2]</plan><feasibility>{}</feasibility>", "'id' and 'desc'"),
        ("<plan>steps = open('x')</plan><feasibility>{}</feasibility>", "Python literal"),
        (
            "<plan>[{'id': 1, 'desc': 'a'}, {'id': 2, 'desc': 'b'}]</plan><feasibility>{(1, 3): True}</feasibility>",
            "not in the plan",
        ),
        (
            "<plan>[{'id': 1, 'desc': 'a'}, {'id': 1, 'desc': 'b'}]</plan><feasibility>{}</feasibility>",
            "duplicate",
        ),
        (
            "<plan>[{'id': 1, 'desc': 'a'}, {'id': 2, 'desc': 'b'}]</plan><feasibility>{(1, 2): 'yes'}</feasibility>",
            "True/False",
        ),
    ],
)
def test_malformed_responses_raise_value_errors_naming_the_tag(text: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        parse_plan_response(text)


def test_recorded_provider_plugs_in_as_an_llm() -> None:
    provider = RecordedProvider.from_files({"lift a block": FIXTURES / "glide_llm_lift.txt"})
    assert isinstance(provider, LLMProvider)
    plan = request_plan(provider, "lift a block from the table.", ["block_pos", "gripper_state"])
    assert plan.num_modes == 3
    prompt = provider.prompts[-1]
    assert "lift a block from the table." in prompt and "'gripper_state'" in prompt and "<feasibility>" in prompt
    with pytest.raises(KeyError, match="no recorded response"):
        provider.complete("stack the blocks")
    with pytest.raises(TypeError, match="complete"):
        request_plan(object(), "task", [])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="task"):
        build_prompt(" ", ["x"])
