"""KitchenClickUser: a different legal skill than the watched one, clicks that map back onto the target, bad input.

One rendered env for the module; states come from reset options (no skill is run).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS

pytestmark = ROBOSUITE_MARKS

#: reset options -> the skills whose target the scene camera sees there
STARTS: tuple[tuple[dict[str, str], tuple[str, ...]], ...] = (
    ({}, ("open_door", "close_door", "pick_bowl", "place_in_sink")),
    ({"door": "open"}, ("pick_bowl", "place_in_sink", "place_in_microwave")),
)


@pytest.fixture(scope="module")
def env() -> Iterator[object]:
    from steer_envs.envs.robosuite.kitchen import KitchenEnv

    made = KitchenEnv(task="microwave", render_mode="rgb_array", fast_render=True)
    yield made
    made.close()


def _mode(env: object) -> str:
    return str(env.task.modes[env._mode])  # type: ignore[attr-defined]


def test_the_intended_skill_is_legal_and_not_the_watched_one(env: object) -> None:
    from steer_envs.envs.robosuite.kitchen import legal_skills
    from steer_envs.users.kitchen_clicker import KitchenClickUser

    user = KitchenClickUser(3)
    for options in ({}, {"door": "open"}, {"bowl": "microwave", "door": "open"}, {"bowl": "sink"}):
        env.reset(seed=1, options=options)  # type: ignore[attr-defined]
        legal = legal_skills(_mode(env))
        for watched in (*legal, None):
            chosen = {user.intended_skill(env, watched) for _ in range(12)}
            assert chosen == set(legal) - {watched}, (options, watched, chosen)
    env.reset(seed=1, options={"bowl": "microwave"})  # type: ignore[attr-defined]
    assert legal_skills(_mode(env)) == ("open_door",)
    assert user.intended_skill(env, "open_door") is None and user.act(env, "open_door") is None
    again = [KitchenClickUser(5).intended_skill(env, None) for _ in range(2)]
    assert again[0] == again[1]  # seeded


def test_a_click_maps_back_within_a_centimetre_of_its_target(env: object) -> None:
    from steer_envs.core.interaction import Point
    from steer_envs.users.kitchen_clicker import KitchenClickUser, skill_centre

    user = KitchenClickUser(0)
    for seed in (0, 1):
        for options, skills in STARTS:
            env.reset(seed=seed, options=options)  # type: ignore[attr-defined]
            for skill in skills:
                click = user.click(env, skill, watched=None)
                assert click.visible and click.error < 0.01, (options, skill, click)
                u, v = click.pixel
                back = env.pixel_to_world(u, v)  # type: ignore[attr-defined]  # a fresh depth render
                assert np.linalg.norm(back - click.target) < 0.01, (options, skill)
                assert isinstance(click.interaction, Point) and click.interaction.target.shape == (3,)
                # the aimed point is on the target: near its centre
                assert np.linalg.norm(click.target - skill_centre(env, skill)) < 0.2


def test_bad_input_is_refused(env: object) -> None:
    from steer_envs.users.kitchen_clicker import KitchenClickUser

    user = KitchenClickUser(0)
    with pytest.raises(ValueError, match="skill"):
        user.click(env, "wash_bowl")
    with pytest.raises(ValueError, match="skill"):
        user.intended_skill(env, "fly")
    with pytest.raises(TypeError, match="env"):
        user.click(object(), "pick_bowl")
    with pytest.raises(ValueError, match="seed"):
        KitchenClickUser(-1)
    with pytest.raises(TypeError, match="camera"):
        KitchenClickUser(0, camera=3)  # type: ignore[arg-type]
