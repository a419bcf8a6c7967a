"""SoupScoop-v0: the 2D soup-scooping abstraction of TLI (thesis §3.2 Fig. 3.2, §3.6).

The state ``x = (x1, x2)`` in ``[-8, 8]^2`` abstracts the spoon's orientation
and its distance to the soup. Regions (rectangles ``[x0, x1] x [y0, y1]``, as
in the public TLI code):

=========  ==========================  =====================================
region     rectangle                   meaning
=========  ==========================  =====================================
white      everything else             spoon without soup
yellow R   ``[-8, 8] x [-8, -4]``      spoon in contact with the soup
pink S     ``[2, 6] x [-8, 6]``        spoon holding soup (transport)
green T    ``[2, 6] x [6, 8]``         spoon at the target
=========  ==========================  =====================================

Where regions overlap the later one wins (pink over yellow, green over pink),
and a point within ``0.4`` of a region's attractor counts as in that region
(the segment attractors of the public demonstrations: yellow
``(-6.47, -4.13)``, pink ``(2.06, -6.98)``, green ``(4.69, 6.03)``), so a DS
converging to its attractor does trigger the next sensor.

Physics (task memory: ``soup`` on the spoon, soup ``delivered``):

* Soup gets on the spoon only by moving from the yellow region into the pink
  region (scooping). White -> pink never loads soup: the mode stays ``a``.
* Soup stays on while the spoon is in the transport region (pink or green)
  and falls off when it leaves it (into white or back into yellow): a *spill*,
  reported as ``info["constraint_violation"]`` (an invariance failure of mode
  ``c``). Leaving the soup (yellow -> white) before scooping is an allowed
  recovery (``b -> a``), not a violation.
* Reaching green with soup delivers it: mode ``d``, ``info["success"]``; ``d``
  absorbs (the memory is frozen once delivered).
* Green without soup is just mode ``a`` (reaching).

Sensor APs ``("r", "s", "t")``: ``r`` the spoon is in the soup (yellow),
``s`` soup is on the spoon, ``t`` the soup arrived at the target. With the
default ``sensor_convention="public"`` the env emits the sensor states of the
public automaton table (a ``000``, b ``100``, c ``010``, d ``011``: the soup is
still on the spoon at the target). ``sensor_convention="thesis"`` emits the
thesis's appendix formula instead (d ``001``: the soup left the spoon into the
target). The :data:`SOUP_TASK` ``sensor_modes`` map *both* readings of ``d``,
so ``task.mode_of(info["sensors"]) == info["mode_name"]`` under either
convention. ``t`` is never true without soup, so an empty spoon in green is
never mistaken for ``d``.

Modes: ``a`` reach, ``b`` scoop, ``c`` transport, ``d`` done. Transitions
(thesis Fig. 3.3a): ``a -> b -> c -> d`` plus the recoveries ``b -> a``,
``c -> a``, ``c -> b``. Violations do not end the episode
(``terminate_on_violation=False``): TLI recovers by replanning.

Dynamics: ``x' = x + dt * u``, ``dt = 0.01``, ``|u| <= 10`` (a step long
enough for perturbed DS rollouts to fit the registered 1000-step limit). Starts are uniform in
``[-7.5, -5.5] x [1, 5]`` (white, above the first segment attractor, where
the reach segment of the demonstrations begins).

Description
    See above. The modes keep the thesis's ids ``a``-``d`` (``info["mode_name"]``, the LTL specs);
    ``task.labels`` are ``reach``, ``scoop``, ``transport``, ``done`` and either name is accepted wherever a
    mode is looked up (``task.mode_index("scoop") == 1``, ``task.label_of(info["mode"])``).

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``r``, ``s``, ``t`` as 0/1. "Soup on the
    spoon" (``s``) is task memory, not a function of xy: observe it this way.

Action
    ``Box(-10, 10, (2,), float32)``: a velocity, ``x' = x + 0.01 u`` with ``|u|`` clipped to 10;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 10.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage = the mode (reach 0, scoop 1,
    transport 2, done 3), sub-goal = the mode's segment attractor (yellow's, green's), but the centre ``(4, -6)`` of the
    scoop zone (pink over yellow) for scoop: pink's attractor lies at the zone's edge, where scoops spill on the way up.

Termination
    On success (soup delivered to the target). Spills are reported, never terminal; truncation at 1000
    steps (registered).

Registered ids
    ``steer_envs/SoupScoop-v0``, ``steer_envs/SoupScoopDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Literal, Unpack

import numpy as np

from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import describe, one_of
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, RectRegionsModel, TaskReading
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import REGION_PALETTE, Canvas

#: half-width of the square workspace ``[-8, 8]^2``.
WORKSPACE_HALF_WIDTH = 8.0
#: region labels returned by :meth:`SoupScoopModel.regions`.
WHITE, YELLOW, PINK, GREEN = 0, 1, 2, 3
REGION_NAMES: tuple[str, ...] = ("white", "yellow", "pink", "green")
#: closed rectangles ``(x0, y0, x1, y1)`` of the coloured regions (later wins).
RECTS: MappingProxyType[str, tuple[float, float, float, float]] = MappingProxyType(
    {
        "yellow": (-8.0, -8.0, 8.0, -4.0),
        "pink": (2.0, -8.0, 6.0, 6.0),
        "green": (2.0, 6.0, 6.0, 8.0),
    }
)
#: per-region attractors of the public demonstrations' segments.
REGION_ATTRACTORS: MappingProxyType[str, tuple[float, float]] = MappingProxyType(
    {"yellow": (-6.47, -4.13), "pink": (2.06, -6.98), "green": (4.69, 6.03)}
)
#: a point within this distance of a region's attractor counts as in the region.
ATTRACTOR_RADIUS = 0.4
#: dense-reward sub-goal of the scoop mode: the centre of the scoop zone (pink over yellow). Not pink's segment
#: attractor, which lies 0.06 inside the zone's left edge: a scoop through its disc, left of the edge, spills on
#: the way up, so shaping toward it rewards the spill-prone edge.
SCOOP_SUBGOAL = (4.0, -6.0)
#: attractor of the unsegmented task (public TLI code).
TASK_ATTRACTOR = (4.75, 5.99)
#: start box ``(low, high)`` corners.
START_BOX = ((-7.5, 1.0), (-5.5, 5.0))

SOUP_TASK = TaskSpec(
    name="SoupScoop",
    modes=("a", "b", "c", "d"),
    sensors=("r", "s", "t"),
    sensor_modes={
        frozenset(): "a",
        frozenset({"r"}): "b",
        frozenset({"s"}): "c",
        frozenset({"s", "t"}): "d",  # public automaton table (soup still on the spoon at the target)
        frozenset({"t"}): "d",  # thesis appendix formula (soup delivered into the target)
    },
    transitions=frozenset({("a", "b"), ("b", "c"), ("c", "d"), ("b", "a"), ("c", "a"), ("c", "b")}),
    initial="a",
    goal=("d",),
    labels=("reach", "scoop", "transport", "done"),
)

MODE_A, MODE_B, MODE_C, MODE_D = range(4)
SensorConvention = Literal["public", "thesis"]


class SoupScoopModel(RectRegionsModel):
    """Batched task physics of SoupScoop; see the module docstring.

    Public geometry (float64 arrays):
        rects: region name -> ``(x0, y0, x1, y1)`` closed rectangle.
        region_attractors: region name -> ``(2,)`` attractor (in-region within
            ``attractor_radius``).
        attractors: mode name -> ``(2,)`` the goal of that mode's policy
            (``a``: yellow's, ``b``: pink's, ``c`` and ``d``: green's; the done
            mode reuses the transport DS, as in the public code).
        task_attractor: ``(2,)`` attractor of the unsegmented task.
        dense_subgoals: ``(4, 2)`` the dense reward's sub-goal of each mode (:meth:`progress`).
        start_low, start_high: corners of the uniform start box.

    Task memory (2 slots): ``[soup on the spoon, soup delivered]``.
    """

    memory_size = 2
    region_names = REGION_NAMES
    region_palette = REGION_PALETTE[[0, 1, 2, 3]]

    def __init__(self, sensor_convention: SensorConvention = "public") -> None:
        if not isinstance(sensor_convention, str):
            raise TypeError(
                f"SoupScoop: sensor_convention must be 'public' or 'thesis', got {describe(sensor_convention)}"
            )
        self.sensor_convention = one_of(sensor_convention, "sensor_convention", ("public", "thesis"), owner="SoupScoop")
        self.task = SOUP_TASK
        # rectangles in label order (yellow, pink, green) for the one-pass labelling in `regions`
        self.set_geometry(WORKSPACE_HALF_WIDTH, RECTS, REGION_NAMES[1:], START_BOX)
        self.region_attractors = {k: np.asarray(v, dtype=np.float64) for k, v in REGION_ATTRACTORS.items()}
        self.attractor_radius = ATTRACTOR_RADIUS
        self.attractors = {
            "a": self.region_attractors["yellow"],
            "b": self.region_attractors["pink"],
            "c": self.region_attractors["green"],
            "d": self.region_attractors["green"],
        }
        self.task_attractor = np.asarray(TASK_ATTRACTOR, dtype=np.float64)
        # dense-reward sub-goals in mode order a..d (see `progress`)
        scoop = np.asarray(SCOOP_SUBGOAL, dtype=np.float64)
        self.dense_subgoals = np.stack([self.attractors["a"], scoop, self.attractors["c"], self.attractors["d"]])
        self._att_stack = np.stack([self.region_attractors[n] for n in REGION_NAMES[1:]])

    # ------------------------------------------------------------ geometry
    def in_region(self, name: str, pos: np.ndarray) -> np.ndarray:
        """Whether points lie in region ``name``'s rectangle or attractor disc, ignoring overlaps.

        ``(N, 2) -> (N,)`` bool. Use :meth:`regions` for the label after the
        "later region wins" rule.
        """
        one_of(name, "name", tuple(self.rects), owner="SoupScoop.in_region")
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        x0, y0, x1, y1 = self.rects[name]
        in_rect = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
        near = np.linalg.norm(p - self.region_attractors[name], axis=1) <= self.attractor_radius
        return in_rect | near

    def regions(self, pos: np.ndarray) -> np.ndarray:
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 1, 2)
        near = np.sum((p - self._att_stack) ** 2, axis=-1) <= self.attractor_radius**2
        return self.last_label(self.in_rects(pos) | near)

    # ---------------------------------------------------------------- task
    def advance(self, memory: np.ndarray, prev_pos: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        prev_reg, new_reg = self.regions(prev_pos), self.regions(pos)
        soup, delivered = memory[:, 0].astype(bool), memory[:, 1].astype(bool)
        in_transport = (new_reg == PINK) | (new_reg == GREEN)
        scooped = ~soup & (prev_reg == YELLOW) & (new_reg == PINK)
        spill = ~delivered & soup & ~in_transport
        new_soup = np.where(delivered, soup, (soup & in_transport) | scooped)
        new_delivered = delivered | (new_soup & (new_reg == GREEN))
        new_memory = np.stack([new_soup, new_delivered], axis=1).astype(np.int64)
        return new_memory, spill

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        reg = self.regions(pos)
        soup, delivered = memory[:, 0].astype(bool), memory[:, 1].astype(bool)
        in_soup = ~delivered & ~soup & (reg == YELLOW)
        mode = np.where(delivered, MODE_D, np.where(soup, MODE_C, np.where(in_soup, MODE_B, MODE_A)))
        s = (soup & ~delivered) | (delivered & (self.sensor_convention == "public"))
        sensors = np.stack([in_soup, s, delivered], axis=1)
        return TaskReading(mode=mode.astype(np.int64), sensors=sensors, success=delivered.copy())

    num_stages = 3

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage = the mode (reach 0 ... done 3); sub-goal = :attr:`dense_subgoals` (the mode's attractor, but
        the centre of the scoop zone for scoop)."""
        mode = self.read(memory, pos).mode
        goals = self.dense_subgoals[mode]
        distance = np.where(mode == MODE_D, 0.0, np.linalg.norm(np.asarray(pos, dtype=np.float64) - goals, axis=1))
        return mode, distance

    def draw(self, canvas: Canvas) -> None:
        radius = max(2, round(self.attractor_radius / (self.high[0] - self.low[0]) * canvas.width))
        for name in ("yellow", "pink", "green"):
            x0, y0, x1, y1 = self.rects[name]
            corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]])
            canvas.polyline(corners, (150, 150, 150), thickness=1)
            canvas.disc(self.region_attractors[name], radius, (255, 140, 0))


class SoupScoopEnv(Kinematic2DEnv):
    """SoupScoop-v0 (TLI soup scooping, reach -> scoop -> transport -> done); see the module docstring.

    Args:
        dt, max_speed: integration step and speed limit (0.01, 10).
        sensor_convention: ``"public"`` (d = s & t, default) or ``"thesis"`` (d = t).
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).

    Spills are reported, never terminal (``terminate_on_violation=False``).
    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/SoupScoop-v0")
    >>> obs, info = env.reset(seed=0)
    >>> info["mode_name"], info["sensors"]
    ('a', {'r': False, 's': False, 't': False})
    >>> info = env.unwrapped.perturb(to=[0.0, -6.0])  # pushed into the soup
    >>> info["mode_name"], info["perturbed"]
    ('b', True)
    """

    def __init__(
        self,
        dt: float = 0.01,
        max_speed: float = 10.0,
        sensor_convention: SensorConvention = "public",
        **options: Unpack[EnvOptions],
    ) -> None:
        super().__init__(
            SoupScoopModel(sensor_convention=sensor_convention),
            dt=dt,
            max_speed=max_speed,
            terminate_on_violation=False,
            **options,
        )
        self.model: SoupScoopModel


make_vector_env = vector_factory(SoupScoopEnv)

__all__ = [
    "ATTRACTOR_RADIUS",
    "RECTS",
    "REGION_ATTRACTORS",
    "REGION_NAMES",
    "SOUP_TASK",
    "SoupScoopEnv",
    "SoupScoopModel",
    "make_vector_env",
]
