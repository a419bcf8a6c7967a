"""A simulated Kitchen user who clicks a pixel of the scene camera to switch the robot's next skill (thesis §2.3).

In the kitchen study the user watches the policy's randomly sampled next skill
and, wanting a *different* legal one, clicks a pixel on that skill's target in
the scene camera; the pixel's 3D point (through the depth buffer) is the point
input of the steering samplers. :class:`KitchenClickUser` does that
reproducibly:

* :meth:`~KitchenClickUser.intended_skill`: a seeded draw among the skills
  legal in the current mode (:func:`~steer_envs.envs.robosuite.kitchen.legal_skills`)
  other than the watched one; None when there is no other.
* :meth:`~KitchenClickUser.click`: the skill's target, as a person would aim at
  it: the door handle's bar (door skills), the bowl (``pick_bowl``), the sink
  basin's floor centre (``place_in_sink``), the microwave cavity's floor centre
  (``place_in_microwave``). The scene camera does not see every target point
  (the bowl's floor hides behind its wall, the cavity behind the microwave's
  side wall or the arm), so the user aims at the *visible* point of the target
  nearest its centre: candidate points on the target's surface
  (:meth:`~KitchenClickUser.aim_points`, nearest the centre first), the first
  whose pixel's depth-buffer point lies within :data:`VISIBLE_TOL` of it. When
  none is visible the user clicks where the centre projects (what they would
  see there, e.g. the arm, becomes the point). The click is a whole pixel; its
  world point comes from :meth:`pixel_to_world` on the env's depth render, as
  the env must be made with ``render_mode="rgb_array"``.

The interaction is a :class:`~steer_envs.core.interaction.Point` on the plan's
xyz dims (the Kitchen policy's ``interaction_dims`` are ``(0, 1, 2)``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from steer_envs.core.interaction import Point
from steer_envs.core.validation import integer
from steer_envs.envs.robosuite.kitchen import SKILLS, KitchenEnv, legal_skills, skill_centre, unwrap_kitchen
from steer_envs.envs.robosuite.kitchen_assets import BOWL_HEIGHT, BOWL_RADIUS
from steer_envs.envs.robosuite.kitchen_scene import CAVITY_HIGH, CAVITY_LOW, SINK_FLOOR_Z, SINK_SIZE

__all__ = ["SINK_FLOOR_Z", "VISIBLE_TOL", "KitchenClick", "KitchenClickUser", "skill_centre"]

#: a candidate aim point counts as visible when its pixel's depth-buffer point is within this distance (m).
VISIBLE_TOL = 0.01
_BAR_SPAN = 0.1  # m: aim points up and down the handle bar from its centre
_HANDLE_RADIUS = 0.015  # m: the handle bar's capsule radius (FrankaKitchen's microwave at this scale)


@dataclass(frozen=True)
class KitchenClick:
    """One click and what it is for.

    Attributes:
        skill: the skill the user means.
        watched: the skill the user watched the policy sample (None: not given).
        pixel: ``(u, v)``: column and row of the clicked pixel in the scene camera (image convention).
        point: ``(3,)`` the clicked world point (depth buffer, m).
        target: ``(3,)`` the point of the target the user aimed at (m).
        visible: some aim point of the target was visible (else the centre's pixel was clicked).
    """

    skill: str
    watched: str | None
    pixel: tuple[int, int]
    point: np.ndarray
    target: np.ndarray
    visible: bool
    interaction: Point = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "interaction", Point(np.asarray(self.point, dtype=np.float64), dim=3))

    @property
    def error(self) -> float:
        """Distance (m) from the clicked world point to the aimed target point."""
        return float(np.linalg.norm(np.asarray(self.point) - np.asarray(self.target)))


def _mode(env: KitchenEnv) -> str:
    return str(env.task.modes[env._mode])


def _check_skill(skill: Any, owner: str) -> str:
    if not isinstance(skill, str) or skill not in SKILLS:
        raise ValueError(f"{owner}: `skill` must be one of {list(SKILLS)}, got {skill!r}")
    return skill


class KitchenClickUser:
    """A user who watches a sampled skill, wants another legal one and clicks its target (see the module docstring).

    Args:
        seed: seeds the choice of the intended skill (an int >= 0).
        camera: the camera clicked in (None: the env's, the scene camera by default).
    """

    def __init__(self, seed: int = 0, *, camera: str | None = None) -> None:
        self.seed = integer(seed, "seed", low=0, owner="KitchenClickUser")
        if camera is not None and not isinstance(camera, str):
            raise TypeError(f"KitchenClickUser: `camera` must be a str or None, got {type(camera).__name__}")
        self.camera = camera
        self.rng = np.random.default_rng([self.seed, 18])

    def intended_skill(self, env: Any, watched: str | None) -> str | None:
        """A legal skill of ``env``'s mode other than ``watched`` (a seeded draw); None if there is none."""
        owner = "KitchenClickUser.intended_skill"
        base = unwrap_kitchen(env, owner)
        if watched is not None:
            _check_skill(watched, owner)
        options = [s for s in legal_skills(_mode(base)) if s != watched]
        if not options:
            return None
        return options[int(self.rng.integers(len(options)))]

    def aim_points(self, env: Any, skill: str) -> np.ndarray:
        """``(K, 3)`` points on ``skill``'s target the user may aim at, nearest the target's centre first."""
        owner = "KitchenClickUser.aim_points"
        base = unwrap_kitchen(env, owner)
        skill = _check_skill(skill, owner)
        centre = skill_centre(base, skill)
        eye = self._eye(base)
        if skill in ("open_door", "close_door"):
            toward = eye[:2] - centre[:2]
            toward = toward / max(float(np.linalg.norm(toward)), 1e-9)
            dz = np.linspace(-_BAR_SPAN, _BAR_SPAN, 21)
            pts = np.repeat(centre[None], len(dz), axis=0)
            pts[:, :2] += _HANDLE_RADIUS * toward  # on the bar's surface facing the camera
            pts[:, 2] += dz
        elif skill == "pick_bowl":
            angles = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
            rim = centre + np.stack(
                [BOWL_RADIUS * np.cos(angles), BOWL_RADIUS * np.sin(angles), np.full_like(angles, BOWL_HEIGHT / 2)], 1
            )
            wall = rim - [0.0, 0.0, BOWL_HEIGHT / 2]
            pts = np.concatenate([centre[None] - [0.0, 0.0, BOWL_HEIGHT / 2 - 0.006], wall, rim])
        elif skill == "place_in_sink":
            half = np.asarray(SINK_SIZE[:2]) / 2 - 0.02
            gx, gy = np.meshgrid(np.linspace(-half[0], half[0], 9), np.linspace(-half[1], half[1], 9))
            pts = np.stack([centre[0] + gx.ravel(), centre[1] + gy.ravel(), np.full(gx.size, SINK_FLOOR_Z)], 1)
        else:
            xs = np.linspace(CAVITY_LOW[0] + 0.005, CAVITY_HIGH[0] - 0.02, 12)
            ys = np.linspace(CAVITY_LOW[1] + 0.02, CAVITY_HIGH[1] - 0.02, 12)
            gx, gy = np.meshgrid(xs, ys)
            pts = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, CAVITY_LOW[2])], 1)
        order = np.argsort(np.linalg.norm(pts - centre, axis=1), kind="stable")
        return np.asarray(pts[order], dtype=np.float64)

    def _eye(self, env: KitchenEnv) -> np.ndarray:
        name = self.camera or env.camera
        cam_id = env.rs_env.sim.model.camera_name2id(name)
        return np.array(env.rs_env.sim.data.cam_xpos[cam_id], dtype=np.float64)

    def click(self, env: Any, skill: str, watched: str | None = None) -> KitchenClick:
        """Click ``skill``'s target in the camera (see the module docstring); ``watched`` is recorded."""
        owner = "KitchenClickUser.click"
        base = unwrap_kitchen(env, owner)
        skill = _check_skill(skill, owner)
        if watched is not None:
            _check_skill(watched, owner)
        if base.render_mode != "rgb_array":
            raise ValueError(f"{owner}: `env` must be made with render_mode='rgb_array' (the depth buffer)")
        depth = base.render_rgbd(self.camera)[1]
        size = base.render_size

        def seen(p: np.ndarray) -> tuple[tuple[int, int], np.ndarray] | None:
            u, v, _ = base.world_to_pixel(p, camera=self.camera)
            col, row = round(float(u)), round(float(v))
            if not (0 <= col < size and 0 <= row < size):
                return None
            world = base.pixel_to_world(col, row, camera=self.camera, depth=float(depth[row, col]))
            return (col, row), world

        for p in self.aim_points(base, skill):
            hit = seen(p)
            if hit is not None and np.linalg.norm(hit[1] - p) <= VISIBLE_TOL:
                return KitchenClick(skill, watched, hit[0], hit[1], p, True)
        centre = skill_centre(base, skill)
        hit = seen(centre)
        if hit is None:
            raise ValueError(f"{owner}: the target of {skill!r} is outside the camera's frame")
        return KitchenClick(skill, watched, hit[0], hit[1], centre, False)

    def act(self, env: Any, watched: str | None) -> KitchenClick | None:
        """Pick the intended skill against ``watched`` and click it; None when no other legal skill exists."""
        skill = self.intended_skill(env, watched)
        return None if skill is None else self.click(env, skill, watched)
