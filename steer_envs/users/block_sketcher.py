"""A simulated VR user for BlockStack steering: wants one 4-block tower, sketches each skill in 3D (thesis §2.3).

In the block-stacking study a user who wants a particular tower draws, in VR,
a 3D path for each skill: from the end effector up, over the cube to pick (or
the spot the held cube should go) and down to it. :class:`TowerSketchUser`
does that reproducibly:

* :meth:`~TowerSketchUser.intended_skill`: the next skill toward the goal
  tower, by the rule of the expert's ``GoalTowerPlanner``
  (:func:`~steer_envs.control.blockstack.goal_tower_skill`;
  recovery included: a wrong cube held goes to a free table spot, a wrong cube
  on the partial tower is picked off);
* :meth:`~TowerSketchUser.sketch`: the eef path of a skill (for a place, the
  held cube's goal corrected by the held offset, so the *eef* path is drawn)
  as corners up / over / down, corners rounded, a smooth seeded hand jitter
  (``jitter`` m, correlated over ``smoothing`` m of path; none at the start,
  which is the hand), resampled evenly in arc length to ``n_points``.

Everything is a pure function of the seed (and the order of the calls). ``tests/users/test_block_sketcher.py``
(run as a script) checks that the sketch of the intended skill is closer
(ITPS's sketch cost) to the expert's plan of that skill than to the expert's
plans of the other skills from the same state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.control.blockstack import Skill, goal_tower_skill
from steer_envs.core.interaction import Sketch
from steer_envs.core.validation import boolean, integer, one_of, real_array, real_scalar
from steer_envs.envs.robosuite.blockstack import (
    CUBE_HALF,
    NUM_CUBES,
    BlockStackEnv,
    check_goal_order,
    unwrap_blockstack,
)

__all__ = ["CARRY_CLEARANCE", "MIN_CARRY_Z", "RETREAT", "BlockSketch", "TowerSketchUser"]

#: the drawn carry height: this far (m) above the highest other cube's top (the expert's ``carry_clearance``) ...
CARRY_CLEARANCE = 0.07
#: ... and at least this far (m) above the table (the expert's ``min_carry_z``).
MIN_CARRY_Z = 0.15
#: a place's follow-through: up this far (m) after the target (the expert's ``retreat``).
RETREAT = 0.08
_DENSE = 256  # points of the dense path the jitter is drawn on
_RAMP = 0.05  # m: the jitter grows from zero at the hand over this much path


@dataclass(frozen=True)
class BlockSketch:
    """One drawn sketch and what it is for.

    Attributes:
        sketch: the 3-D eef path (world, m), starting at the end effector.
        skill: the skill the user means.
        target: ``(3,)`` where the user wants the end effector to end (before jitter).
    """

    sketch: Sketch
    skill: Skill
    target: np.ndarray


class TowerSketchUser:
    """A user who wants the tower ``goal_order`` and sketches each skill toward it (see the module docstring).

    Args:
        goal_order: the 4 cube ids bottom to top.
        seed: seeds the table spots the user picks and the hand jitter (an int >= 0).
        n_points: points of every sketch (an int in [2, 100000]).
        jitter: standard deviation (m) of the hand's offset from the ideal path, in [0, 0.05].
        smoothing: the jitter's correlation length along the path (m, > 0; a Gaussian filter's sigma).
        carry_clearance / min_carry_z: the drawn carry height, as the expert's
            (this much above the highest other cube's top, at least this much above the table; m).
        follow_through: also draw the motion after the target, as a skill plan holds it: back
            up to the carry height after a pick, up by the expert's retreat after a place.

    >>> TowerSketchUser((3, 1, 0, 2), seed=4, n_points=16).n_points
    16
    """

    def __init__(
        self,
        goal_order: Sequence[int],
        seed: int = 0,
        *,
        n_points: int = 32,
        jitter: float = 0.01,
        smoothing: float = 0.04,
        carry_clearance: float = CARRY_CLEARANCE,
        min_carry_z: float = MIN_CARRY_Z,
        follow_through: bool = False,
    ) -> None:
        owner = "TowerSketchUser"
        order = check_goal_order(goal_order, owner)
        if order is None:
            raise TypeError(f"{owner}: `goal_order` must be a sequence of the 4 cube ids, got None")
        self.goal_order: tuple[int, ...] = order
        self.seed = integer(seed, "seed", low=0, owner=owner)
        self.n_points = integer(n_points, "n_points", low=2, high=100_000, owner=owner)
        self.jitter = real_scalar(jitter, "jitter", low=0.0, high=0.05, owner=owner)
        self.smoothing = real_scalar(smoothing, "smoothing", low=0.0, low_inclusive=False, high=1.0, owner=owner)
        self.carry_clearance = real_scalar(carry_clearance, "carry_clearance", low=0.0, high=1.0, owner=owner)
        self.min_carry_z = real_scalar(min_carry_z, "min_carry_z", low=0.0, high=1.0, owner=owner)
        self.follow_through = boolean(follow_through, "follow_through", owner=owner)
        plan_seed, hand_seed = np.random.SeedSequence(self.seed).spawn(2)
        self.spot_rng = np.random.default_rng(plan_seed)  # the table spots the user chooses
        self.rng = np.random.default_rng(hand_seed)  # the hand's jitter

    # ------------------------------------------------------------------ API
    def intended_skill(self, env: Any) -> Skill:
        """The next skill toward the goal tower from ``env``'s state (a table place draws a new free spot)."""
        base = unwrap_blockstack(env, "TowerSketchUser.intended_skill")
        return goal_tower_skill(base, self.goal_order, self.spot_rng)

    def target(self, env: Any, skill: Skill) -> np.ndarray:
        """``(3,)``: where the eef should end (a pick's cube centre; a place's goal less the held offset)."""
        owner = "TowerSketchUser.target"
        base = unwrap_blockstack(env, owner)
        skill = _check_skill(skill, owner)
        pos = base.cube_pos
        held = base.held_cube
        if skill.kind == "pick":
            if held is not None:
                raise ValueError(f"{owner}: `skill` picks cube {skill.cube} but the hand holds {held}")
            return pos[skill.cube].copy()
        if held != skill.cube:
            raise ValueError(f"{owner}: `skill` places cube {skill.cube} but the hand holds {held}")
        if skill.onto is None:
            assert skill.xy is not None
            goal = np.array([skill.xy[0], skill.xy[1], base.table_z + CUBE_HALF])
        else:
            goal = pos[skill.onto] + np.array([0.0, 0.0, 2 * CUBE_HALF])
        return np.asarray(goal - (pos[held] - base.state), dtype=np.float64)

    def sketch(self, env: Any, skill: Skill) -> Sketch:
        """The drawn 3-D eef path for ``skill`` from ``env``'s state (``n_points`` points, world m)."""
        return self._draw(env, skill, "TowerSketchUser.sketch").sketch

    def draw(self, env: Any) -> BlockSketch:
        """The intended skill and its sketch."""
        owner = "TowerSketchUser.draw"
        return self._draw(env, self.intended_skill(unwrap_blockstack(env, owner)), owner)

    # ------------------------------------------------------------ internals
    def _carry_z(self, env: BlockStackEnv, moving: int) -> float:
        pos = env.cube_pos
        tops = [pos[k, 2] + CUBE_HALF for k in range(NUM_CUBES) if k != moving]
        return max(max(tops) + self.carry_clearance, env.table_z + self.min_carry_z)

    def _draw(self, env: Any, skill: Skill, owner: str) -> BlockSketch:
        base = unwrap_blockstack(env, owner)
        skill = _check_skill(skill, owner)
        goal = self.target(base, skill)
        eef = base.state
        z = max(self._carry_z(base, skill.cube), float(eef[2]))
        corners = np.array([eef, [eef[0], eef[1], z], [goal[0], goal[1], z], goal], dtype=np.float64)
        if self.follow_through:
            up = z if skill.kind == "pick" else goal[2] + RETREAT
            corners = np.vstack([corners, [goal[0], goal[1], up]])
        corners = _chaikin(_dedupe(corners))
        dense, arc = _resample(corners, _DENSE)
        if self.jitter > 0.0 and arc[-1] > 0.0:
            dense = dense + self._hand(arc)
        points, _ = _resample(dense, self.n_points)
        return BlockSketch(Sketch(points), skill, goal)

    def _hand(self, arc: np.ndarray) -> np.ndarray:
        """``(len(arc), 3)`` smooth jitter: white noise low-passed along the path, std ``jitter``, zero at the hand."""
        n = len(arc)
        step = arc[-1] / (n - 1)
        sigma = max(self.smoothing / step, 1e-6)
        half = int(np.ceil(3 * sigma))
        taps = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
        taps /= np.sqrt(np.sum(taps**2))  # unit gain on white noise: the filtered std stays 1
        noise = self.rng.normal(size=(n + 2 * half, 3))
        smooth = np.stack([np.convolve(noise[:, d], taps, mode="valid") for d in range(3)], axis=1)
        ramp = np.clip(arc / _RAMP, 0.0, 1.0)[:, None]
        return np.asarray(self.jitter * ramp * smooth[:n], dtype=np.float64)


def _check_skill(skill: Any, owner: str) -> Skill:
    if not isinstance(skill, Skill):
        raise TypeError(f"{owner}: `skill` must be a Skill, got {type(skill).__name__}")
    one_of(skill.kind, "`skill.kind`", ("pick", "place"), owner=owner)
    integer(skill.cube, "`skill.cube`", low=0, high=NUM_CUBES - 1, owner=owner)
    if skill.onto is not None:
        integer(skill.onto, "`skill.onto`", low=0, high=NUM_CUBES - 1, owner=owner)
        if skill.onto == skill.cube:
            raise ValueError(f"{owner}: `skill.onto` must be another cube than `skill.cube`, got {skill.onto}")
    elif skill.kind == "place":
        if skill.xy is None:
            raise ValueError(f"{owner}: `skill` is a table place without `skill.xy`")
        real_array(skill.xy, "`skill.xy`", shape=(2,), owner=owner)
    return skill


def _dedupe(points: np.ndarray) -> np.ndarray:
    """Drop corners that repeat the previous one (zero-length segments), the last kept."""
    keep = [0] + [i for i in range(1, len(points)) if np.linalg.norm(points[i] - points[i - 1]) > 1e-9]
    return points[keep] if len(keep) > 1 else points[[0, -1]]


def _chaikin(corners: np.ndarray) -> np.ndarray:
    """One corner-cutting pass, endpoints kept (a hand rounds corners)."""
    if len(corners) <= 2:
        return corners
    q = 0.75 * corners[:-1] + 0.25 * corners[1:]
    r = 0.25 * corners[:-1] + 0.75 * corners[1:]
    return np.vstack([corners[:1], np.stack([q, r], axis=1).reshape(-1, 3), corners[-1:]])


def _resample(path: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points evenly in arc length along ``path`` and their arc lengths (a zero-length path repeats its point)."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, cum[-1], n)
    if cum[-1] <= 0.0:
        return np.repeat(path[:1], n, axis=0), s
    return np.stack([np.interp(s, cum, path[:, d]) for d in range(path.shape[1])], axis=1), s
