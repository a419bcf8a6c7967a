"""The scripted expert of BlockStack: pick-and-place skills on delta OSC and the random tower planner.

:class:`BlockStackSkills` runs one skill at a time on the unwrapped
:class:`~steer_envs.envs.robosuite.blockstack.BlockStackEnv` with a proportional
delta-OSC action (gain 10, clipped to [-1, 1]); the fingers are kept pointing
straight down, the gripper's yaw is matched to the cube's modulo 90 degrees
before grasping, and the held cube's to the supporting cube's before placing on
it (so towers stand square).

- ``pick(i)``: up to the carry height, over cube i, down to its centre, close, lift.
- ``place_on_table(xy)`` / ``place_on(j)``: over the target (the held cube's
  centre, using the held offset re-read every step; slowly, and down only once
  the cube has stopped swinging in the fingers), down until the cube is just
  above the surface, open, back up. Yaw targets stay within 45 degrees of the
  arm's start yaw (turning the shortest way every time winds the wrist up to
  a joint limit over a long episode).

:class:`RandomTowerPlanner` is the random planner of the study: when free it
picks a random top cube; when holding it places on the table at a free spot
(:func:`free_table_spot`: clear of the cubes, and farther from towers, which
the hand would hit) or on top of another tower; now and then it dismantles a partial tower and
rebuilds it (in reverse order) at a new spot. :class:`GoalTowerPlanner` builds
one tower instead. :class:`BlockStackExpert` chains a planner and the skills and
is the registry's expert for ``steer_envs/BlockStack-v0``. Everything is seeded.

:class:`~steer_envs.control.blockstack.Skill`,
:func:`~steer_envs.control.blockstack.free_table_spot`, the goal-tower rule and
the P-control step are defined in :mod:`steer_envs.control.blockstack` (the
plan tracker and the simulated user share them, and the control layer is below
both).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from steer_envs.control.blockstack import (
    Skill,
    free_table_spot,
    goal_tower_skill,
    move_action,
    quarter_turn,
)
from steer_envs.control.blockstack import towers as _towers
from steer_envs.control.blockstack import yaw_of as _yaw
from steer_envs.core.validation import integer, one_of, real_array, real_scalar
from steer_envs.envs.robosuite.blockstack import CUBE_HALF, NUM_CUBES, BlockStackEnv

__all__ = [
    "BlockStackExpert",
    "BlockStackSkills",
    "GoalTowerPlanner",
    "RandomTowerPlanner",
]


def _check_env(env: Any, owner: str) -> BlockStackEnv:
    if not isinstance(env, BlockStackEnv):
        raise TypeError(f"{owner}: `env` must be a BlockStackEnv, got {type(env).__name__}")
    return env


class BlockStackSkills:
    """Closed-loop pick / place skills; call :meth:`start` with a :class:`Skill`, then :meth:`act` until ``done``.

    ``done`` is set when the skill's last phase ends; :meth:`succeeded` says
    whether the world now shows its outcome (the cube held / resting on the target).
    """

    carry_clearance = 0.07  # m: the eef rides this far above the highest other cube's top
    min_carry_z = 0.15  # m above the table
    close_steps = 10
    open_steps = 8
    retreat = 0.08  # m up after a place
    phase_limit = 120  # control steps one phase may take before the skill gives up
    min_descent = 0.1  # action units: the slowest lowering of a held cube
    carry_speed = 0.5  # action units: a held cube swings less on a slower carry
    level_cos = 0.99  # a held cube goes down once a face points up within ~8 degrees ...
    settle_steps = 80  # ... or after this many steps of the carry anyway

    def __init__(self, env: BlockStackEnv) -> None:
        self.env = _check_env(env, type(self).__name__)
        self.skill: Skill | None = None
        self.phase = "done"
        self.count = 0
        self.steps = 0
        self.target = np.zeros(3)
        #: the eef yaw when the skills were made (the arm's start yaw): yaw targets stay within 45 degrees of it
        self.home_yaw = _yaw(env.robosuite_obs["robot0_eef_quat"])

    @property
    def done(self) -> bool:
        """The current skill has finished (or none was started)."""
        return self.phase in ("done", "failed")

    def start(self, skill: Skill) -> None:
        """Begin ``skill`` (a :class:`Skill` whose cube ids are in 0..3)."""
        if not isinstance(skill, Skill):
            raise TypeError(f"BlockStackSkills.start: `skill` must be a Skill, got {type(skill).__name__}")
        one_of(skill.kind, "skill.kind", ("pick", "place"), owner="BlockStackSkills.start")
        integer(skill.cube, "skill.cube", low=0, high=NUM_CUBES - 1, owner="BlockStackSkills.start")
        if skill.kind == "place" and skill.onto is None:
            if skill.xy is None:
                raise ValueError("BlockStackSkills.start: a table place needs `skill.xy`")
            real_array(skill.xy, "skill.xy", shape=(2,), owner="BlockStackSkills.start")
        if skill.onto is not None:
            integer(skill.onto, "skill.onto", low=0, high=NUM_CUBES - 1, owner="BlockStackSkills.start")
            if skill.onto == skill.cube:
                raise ValueError("BlockStackSkills.start: `skill.onto` must be another cube")
        self.skill, self.phase, self.count, self.steps = skill, "up", 0, 0

    def pick(self, i: int) -> None:
        """Start picking cube ``i``."""
        self.start(Skill("pick", i))

    def place_on_table(self, xy: Any) -> None:
        """Start placing the held cube on the table with its centre at ``xy`` (2 reals, m)."""
        held = self._held_or_raise("place_on_table")
        xy = real_array(xy, "xy", shape=(2,), owner="BlockStackSkills.place_on_table")
        self.start(Skill("place", held, None, (float(xy[0]), float(xy[1]))))

    def place_on(self, j: int) -> None:
        """Start placing the held cube on cube ``j`` (the top of its tower)."""
        self.start(Skill("place", self._held_or_raise("place_on"), integer(j, "j", low=0, high=NUM_CUBES - 1)))

    def _held_or_raise(self, who: str) -> int:
        held = self.env.held_cube
        if held is None:
            raise ValueError(f"BlockStackSkills.{who}: no cube is held")
        return held

    # ------------------------------------------------------------- control
    def _carry_z(self, moving: int) -> float:
        pos = self.env.cube_pos
        tops = [pos[k, 2] + CUBE_HALF for k in range(NUM_CUBES) if k != moving]
        return max(max(tops) + self.carry_clearance, self.env.table_z + self.min_carry_z)

    def _move(self, target: np.ndarray, gripper: float, yaw_error: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        return move_action(self.env, target, gripper, yaw_error)

    def _turn(self, eef_yaw: float, yaw: float) -> float:
        """The eef yaw change to a yaw equal to ``yaw`` modulo 90 degrees, the one nearest the start yaw."""
        return quarter_turn(self.home_yaw, eef_yaw, yaw)

    def _next(self, phase: str) -> None:
        self.phase, self.count = phase, 0

    def act(self) -> np.ndarray:
        """The action of the current phase (a zero move with the gripper as it was once ``done``)."""
        env, skill = self.env, self.skill
        if skill is None or self.done:
            return np.array([0, 0, 0, 0, 0, 0, env._gripper], dtype=np.float32)
        self.steps += 1
        self.count += 1
        if self.count > self.phase_limit:
            self._next("failed")
            return np.array([0, 0, 0, 0, 0, 0, env._gripper], dtype=np.float32)
        eef_yaw = _yaw(env.robosuite_obs["robot0_eef_quat"])
        z_carry = self._carry_z(skill.cube)
        if skill.kind == "pick":
            return self._pick_action(skill, eef_yaw, z_carry)
        return self._place_action(skill, eef_yaw, z_carry)

    def _pick_action(self, skill: Skill, eef_yaw: float, z_carry: float) -> np.ndarray:
        """A pick's phases: up to the carry height, over the cube (turned square to it), down, close, lift."""
        env = self.env
        eef, cube = env.state, env.cube_pos[skill.cube]
        grip_yaw = self._turn(eef_yaw, _yaw(env.cube_quat[skill.cube]))
        if self.phase == "up":
            action, d = self._move(np.array([eef[0], eef[1], max(eef[2], z_carry)]), -1)
            if abs(d[2]) < 0.02:
                self._next("over")
        elif self.phase == "over":
            action, d = self._move(np.array([cube[0], cube[1], z_carry]), -1, grip_yaw)
            if np.linalg.norm(d[:2]) < 0.008 and abs(grip_yaw) < 0.05:
                self._next("down")
        elif self.phase == "down":
            action, d = self._move(cube, -1, grip_yaw)
            if np.linalg.norm(d) < 0.006 or (self.count > 40 and abs(d[2]) < 0.015):
                self._next("close")
        elif self.phase == "close":
            action, _ = self._move(eef, 1)
            if self.count >= self.close_steps:
                self._next("lift")
        else:  # lift
            action, d = self._move(np.array([eef[0], eef[1], z_carry]), 1)
            if abs(d[2]) < 0.02:
                self._next("done")
        return action

    def _place_goal(self, skill: Skill, eef_yaw: float) -> tuple[np.ndarray, float]:
        """Where a place puts the held cube's centre, and the eef yaw change that squares it to its support."""
        env = self.env
        if skill.onto is None:
            assert skill.xy is not None
            return np.array([skill.xy[0], skill.xy[1], env.table_z + CUBE_HALF]), 0.0
        pos, quat = env.cube_pos, env.cube_quat
        goal = pos[skill.onto] + np.array([0.0, 0.0, 2 * CUBE_HALF])
        in_hand = _yaw(quat[skill.cube]) - eef_yaw  # the held cube's yaw relative to the fingers
        return goal, self._turn(eef_yaw, _yaw(quat[skill.onto]) - in_hand)

    def _place_action(self, skill: Skill, eef_yaw: float, z_carry: float) -> np.ndarray:
        """A place's phases: up, over the target (settled, square), down onto it, open, retreat."""
        env = self.env
        eef, cube = env.state, env.cube_pos[skill.cube]
        # the held cube's centre over the target, using the held offset measured now
        offset = cube - eef
        goal, yaw_err = self._place_goal(skill, eef_yaw)
        if self.phase == "up":
            action, d = self._move(np.array([eef[0], eef[1], max(eef[2], z_carry)]), 1)
            if abs(d[2]) < 0.02:
                self._next("over")
        elif self.phase == "over":
            xy = goal[:2] - offset[:2]
            action, d = self._move(np.array([xy[0], xy[1], z_carry]), 1, yaw_err)
            action[:2] = np.clip(action[:2], -self.carry_speed, self.carry_speed)
            action[5] = np.clip(action[5], -self.carry_speed, self.carry_speed)
            # go down once over the target, square to it, and the cube has stopped swinging in the fingers
            level = _level(env.cube_quat[skill.cube]) > self.level_cos or self.count > self.settle_steps
            if np.linalg.norm(cube[:2] - goal[:2]) < 0.004 and abs(yaw_err) < 0.04 and level:
                self._next("down")
        elif self.phase == "down":
            xy = goal[:2] - offset[:2]
            action, d = self._move(np.array([xy[0], xy[1], goal[2] + 0.003 - offset[2]]), 1, yaw_err)
            # keep descending (the P-term alone creeps: OSC lags a small delta) until the cube sits on the target
            action[2] = np.clip(action[2], -0.5, -self.min_descent)
            if cube[2] - goal[2] < 0.005 or self.count > 80:
                self._next("open")
        elif self.phase == "open":
            action, _ = self._move(eef, -1)
            if self.count >= self.open_steps:
                self.target = eef + np.array([0.0, 0.0, self.retreat])
                self._next("retreat")
        else:  # retreat
            action, d = self._move(self.target, -1)
            if np.linalg.norm(d) < 0.02:
                self._next("done")
        return action

    def succeeded(self) -> bool:
        """Whether the world shows the finished skill's outcome."""
        skill = self.skill
        if skill is None or self.phase != "done":
            return False
        env = self.env
        if skill.kind == "pick":
            return env.held_cube == skill.cube
        if env.held_cube is not None:
            return False
        rest = env.supports[skill.cube]
        if skill.onto is not None:
            return rest == skill.onto
        assert skill.xy is not None
        return rest == "table" and bool(np.linalg.norm(env.cube_pos[skill.cube, :2] - skill.xy) < 0.01)


class RandomTowerPlanner:
    """The random planner: the next :class:`Skill` for the world the env senses now (seeded).

    Free: pick a random tower top (during a dismantle, the dismantled tower's top).
    Holding: with probability ``p_tower`` place on a random other tower lower than
    4 (if any), else on the table at a random free spot. When free, with
    probability ``p_dismantle`` a partial tower (2-3 high) is chosen and moved,
    top first, to a new spot (rebuilt in reverse order there).
    """

    def __init__(self, seed: int = 0, *, p_tower: float = 0.7, p_dismantle: float = 0.2) -> None:
        self.rng = np.random.default_rng(integer(seed, "seed", low=0, owner="RandomTowerPlanner"))
        self.p_tower = real_scalar(p_tower, "p_tower", low=0.0, high=1.0, owner="RandomTowerPlanner")
        self.p_dismantle = real_scalar(p_dismantle, "p_dismantle", low=0.0, high=1.0, owner="RandomTowerPlanner")
        self._moving: list[int] = []  # cubes of a tower being moved, bottom to top (tops leave first)
        self._new_base: int | None = None  # the first moved cube: the base of the rebuilt tower

    def next_skill(self, env: BlockStackEnv) -> Skill:
        """The next skill for ``env``'s current state."""
        env = _check_env(env, "RandomTowerPlanner.next_skill")
        towers = _towers(env)
        held = env.held_cube
        if held is None:
            if not self._moving and self.rng.random() < self.p_dismantle:
                partial = [t for t in towers if 2 <= len(t) < NUM_CUBES]
                if partial:
                    self._moving = list(partial[int(self.rng.integers(len(partial)))])
                    self._new_base = None
            if self._moving:
                return Skill("pick", self._moving[-1])
            tops = [t[-1] for t in towers] or list(range(NUM_CUBES))  # none resting: any cube
            return Skill("pick", int(self.rng.choice(tops)))
        if self._moving and self._moving[-1] == held:
            self._moving.pop()
            if self._new_base is None:
                self._new_base = held
                return Skill("place", held, None, _xy(free_table_spot(env, self.rng, exclude=held)))
            onto = next(t[-1] for t in towers if self._new_base in t)
            if not self._moving:
                self._new_base = None
            return Skill("place", held, onto)
        others = [t for t in towers if held not in t and len(t) < NUM_CUBES]
        if others and self.rng.random() < self.p_tower:
            return Skill("place", held, others[int(self.rng.integers(len(others)))][-1])
        return Skill("place", held, None, _xy(free_table_spot(env, self.rng, exclude=held)))


class GoalTowerPlanner:
    """Builds ``env.goal_order`` (or a seeded random order without one): clear blockers to the table, then stack."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(integer(seed, "seed", low=0, owner="GoalTowerPlanner"))
        self.order: tuple[int, ...] | None = None

    def next_skill(self, env: BlockStackEnv) -> Skill:
        """The next skill toward the goal tower."""
        env = _check_env(env, "GoalTowerPlanner.next_skill")
        if self.order is None:
            order = env.goal_order
            self.order = order if order is not None else tuple(int(c) for c in self.rng.permutation(NUM_CUBES))
        return goal_tower_skill(env, self.order, self.rng)


def _level(quat_xyzw: np.ndarray) -> float:
    """How level a cube is: the largest |z component| of its three axes (1: a face points straight up)."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    return max(abs(2 * (x * z - w * y)), abs(2 * (y * z + w * x)), abs(1 - 2 * (x * x + y * y)))


def _xy(v: np.ndarray) -> tuple[float, float]:
    return float(v[0]), float(v[1])


class BlockStackExpert:
    """The registry's scripted expert: a planner's skills executed one after another.

    Args:
        env: the unwrapped :class:`BlockStackEnv`.
        seed: seeds the planner (and its table spots); the same seed replays the same plan.
        planner: ``"goal"`` (:class:`GoalTowerPlanner`: build the env's goal tower, or a seeded
            random order; the default, so the expert reaches ``success``) or ``"random"``
            (:class:`RandomTowerPlanner`, the planner of the skill dataset).

    ``history`` lists ``(skill, succeeded, steps)`` of every finished skill.
    """

    def __init__(self, env: BlockStackEnv, *, seed: int = 0, planner: str = "goal") -> None:
        self.env = _check_env(env, "BlockStackExpert")
        self.seed = integer(seed, "seed", low=0, owner="BlockStackExpert")
        self.planner_name = one_of(planner, "planner", ("random", "goal"), owner="BlockStackExpert")
        self.skills = BlockStackSkills(env)
        self.history: list[tuple[Skill, bool, int]] = []
        self._new_planner()

    def _new_planner(self) -> None:
        self.planner: RandomTowerPlanner | GoalTowerPlanner = (
            RandomTowerPlanner(self.seed) if self.planner_name == "random" else GoalTowerPlanner(self.seed)
        )

    def reset(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Start over (the planner reseeded) after ``env.reset``."""
        self._new_planner()
        self.skills = BlockStackSkills(self.env)
        self.history = []

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for the current sim state; a finished skill is logged and the next one planned."""
        sk = self.skills
        if sk.skill is not None and sk.done:
            self.history.append((sk.skill, sk.succeeded(), sk.steps))
            sk.skill = None
        if sk.skill is None:
            sk.start(self.planner.next_skill(self.env))
        return sk.act()
