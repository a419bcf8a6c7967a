"""ConvexMode-v0: reach an attractor without leaving one random convex mode.

The single-mode study of TLI (thesis §3.7.1 and appendix "Single-mode
Experiments"): the mode is the convex hull of 10 points drawn uniformly in
``[-6, 6]^2`` inside the workspace ``[-8, 8]^2``; the attractor sits near the
hull's right edge, the demonstrations start at its left-most vertex. A rollout
succeeds when it comes within 0.4 of the attractor without ever having left
the mode; leaving the mode is an invariance failure (a constraint violation).
Dynamics: ``x' = x + dt * u`` with ``dt = 0.01`` and ``|u| <= 20``.

The geometry is a pure function of ``layout_seed`` (``gym.make(id,
layout_seed=7)``), independent of the reset seed that draws start states.
:func:`convex_halfspaces` and :func:`in_halfspaces` are the batched
point-in-convex-polygon test the domain (and PolygonNav) uses.

Description
    See above; the mode names (``task.modes``) are descriptive already.

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``in_mode`` as 0/1.

Action
    ``Box(-20, 20, (2,), float32)``: a velocity, ``x' = x + 0.01 u`` with ``|u|`` clipped to 20;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 20.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage is 1 at success, else 0, sub-goal
    = the attractor (``phi = -1`` once the agent has left the mode: success is then out of reach).

Termination
    On success (within 0.4 of the attractor, never having left the mode) and, with the default
    ``terminate_on_violation=True``, on leaving the mode; truncation at 1000 steps (registered).

Registered ids
    ``steer_envs/ConvexMode-v0``, ``steer_envs/ConvexModeDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

from typing import Any, Unpack

import numpy as np
from shapely.geometry import MultiPoint, Polygon
from shapely.geometry.polygon import orient

from steer_envs.core.rejection import rejection_sample
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import BoundExceeded, integer, real_scalar
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, TaskReading, ViolationLatchModel
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import Canvas

#: half-width of the square workspace ``[-8, 8]^2``.
WORKSPACE_HALF_WIDTH = 8.0
#: the 10 hull points are drawn uniformly in ``[-SAMPLE_HALF_WIDTH, SAMPLE_HALF_WIDTH]^2``.
SAMPLE_HALF_WIDTH = 6.0
NUM_HULL_POINTS = 10
#: success radius around the attractor.
ATTRACTOR_RADIUS = 0.4
#: closed-set tolerance of the half-space test (points on an edge count as inside).
INSIDE_TOL = 1e-9
#: largest accepted ``start_noise`` (half the workspace): wider noise would start almost nowhere inside the mode.
MAX_START_NOISE = WORKSPACE_HALF_WIDTH
#: rounds of rejection sampling for start states (each round redraws every start still outside the mode).
MAX_START_ROUNDS = 10_000
#: redraws of the 10 hull points when they are degenerate (collinear: probability ~0).
MAX_HULL_DRAWS = 1_000

CONVEX_TASK = TaskSpec(
    name="ConvexMode",
    modes=("inside", "outside"),
    sensors=("in_mode",),
    sensor_modes={frozenset({"in_mode"}): "inside", frozenset(): "outside"},
    # re-entering is allowed (e.g. after an external push); leaving is the invariance failure
    transitions=frozenset({("outside", "inside")}),
    initial="inside",
    goal=("inside",),
    ltl="G in_mode",
)


def convex_halfspaces(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-space form ``A x <= b`` of a convex polygon.

    Args:
        vertices: ``(K, 2)`` counter-clockwise vertices (not repeated at the end).

    Returns:
        ``A`` of shape ``(K, 2)`` (unit outward edge normals) and ``b`` of shape
        ``(K,)``; row ``i`` belongs to the edge ``vertices[i] -> vertices[i + 1]``.
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
        raise ValueError(f"vertices must have shape (K>=3, 2), got {v.shape}")
    edges = np.roll(v, -1, axis=0) - v
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)  # right of a CCW edge = outward
    lengths = np.linalg.norm(normals, axis=1)
    if np.any(lengths <= 0):
        raise ValueError("vertices must not repeat consecutively (zero-length edge)")
    a = normals / lengths[:, None]
    b = np.einsum("ij,ij->i", a, v)
    return a, b


def in_halfspaces(a: np.ndarray, b: np.ndarray, pos: np.ndarray, tol: float = INSIDE_TOL) -> np.ndarray:
    """Which points satisfy ``A x <= b + tol``: ``(N, 2) -> (N,)`` bool.

    ``a``/``b`` may also be stacked over ``P`` polygons, ``(P, K, 2)``/``(P, K)``,
    giving an ``(N, P)`` result.
    """
    pos = np.asarray(pos, dtype=np.float64)
    margins = np.einsum("...kd,nd->n...k", a, pos) - b  # (N, [P,] K)
    return np.all(margins <= tol, axis=-1)


def check_layout_seed(layout_seed: Any, owner: str | None = None) -> int:
    """Validate a ``layout_seed`` (a non-negative int, not a bool or a float) and return it as ``int``.

    >>> check_layout_seed("3")
    Traceback (most recent call last):
    TypeError: layout_seed must be an int, got str '3'
    """
    return integer(layout_seed, "layout_seed", low=0, owner=owner)


class ConvexModeModel(ViolationLatchModel):
    """Batched task physics of ConvexMode (one convex mode, one attractor).

    Public geometry (all float64, fixed by ``layout_seed``):
        points: ``(10, 2)`` the sampled points whose convex hull is the mode.
        vertices: ``(K, 2)`` counter-clockwise hull vertices.
        polygon: the mode as a shapely ``Polygon``.
        A, b: half-space form of the mode, ``A x <= b`` (unit outward normals).
        attractor: ``(2,)`` the goal; ``attractor_radius`` = 0.4.
        demo_start: ``(2,)`` where demonstrations start (the left-most vertex,
            moved 5% toward the centroid so it is strictly inside).

    Start distribution: ``start_noise=None`` draws starts uniformly inside the
    mode. A float ``sigma >= 0`` reproduces the TLI protocol: a point drawn
    uniformly on the demonstration path (the segment ``demo_start ->
    attractor``, which the scripted expert follows) plus ``N(0, sigma^2 I)``,
    redrawn until inside the mode (``sigma`` in {0, 1, 5} ~ 0/5/30% noise);
    ``sigma`` must be at most :data:`MAX_START_NOISE` (half the workspace), and
    a start that is still outside after :data:`MAX_START_ROUNDS` redraws raises
    :class:`~steer_envs.core.validation.BoundExceeded`.

    Task memory (1 slot): whether the agent has ever stepped out of the mode.
    Success: inside, within 0.4 of the attractor, and never stepped out.
    """

    memory_size = 1
    region_names = ("outside", "mode")

    def __init__(self, layout_seed: int = 0, start_noise: float | None = None) -> None:
        self.layout_seed = check_layout_seed(layout_seed, "ConvexMode")
        if start_noise is not None:
            start_noise = real_scalar(start_noise, "start_noise", low=0.0, high=MAX_START_NOISE, owner="ConvexMode")
        self.start_noise = start_noise
        self.task = CONVEX_TASK
        self.low = np.full(2, -WORKSPACE_HALF_WIDTH)
        self.high = np.full(2, WORKSPACE_HALF_WIDTH)
        self.attractor_radius = ATTRACTOR_RADIUS

        rng = np.random.default_rng(self.layout_seed)
        for _ in range(MAX_HULL_DRAWS):  # a degenerate hull (collinear points) has probability ~0; redraw then
            points = rng.uniform(-SAMPLE_HALF_WIDTH, SAMPLE_HALF_WIDTH, size=(NUM_HULL_POINTS, 2))
            hull = MultiPoint([tuple(p) for p in points]).convex_hull
            if isinstance(hull, Polygon) and hull.area > 1.0:
                break
        else:  # pragma: no cover - needs MAX_HULL_DRAWS degenerate draws in a row
            raise BoundExceeded(f"ConvexMode: no hull of area > 1 in MAX_HULL_DRAWS={MAX_HULL_DRAWS} draws")
        self.points = points
        self.polygon: Polygon = orient(hull, sign=1.0)
        self.vertices = np.asarray(self.polygon.exterior.coords, dtype=np.float64)[:-1]
        self.A, self.b = convex_halfspaces(self.vertices)
        # attractor (public TLI code): 0.9 * a point on the edge between the two right-most vertices
        # + 0.05 * each of the two left-most vertices; the point on the edge is drawn uniformly
        # on its middle 60% so the attractor is strictly inside, near the right edge.
        by_x = np.argsort(self.vertices[:, 0])
        right = self.vertices[by_x[-2:]]
        left = self.vertices[by_x[:2]]
        t = rng.uniform(0.2, 0.8)
        on_edge = right[0] + t * (right[1] - right[0])
        self.attractor = 0.9 * on_edge + 0.05 * left[0] + 0.05 * left[1]
        centroid = np.asarray(self.polygon.centroid.coords[0])
        self.demo_start = 0.95 * self.vertices[by_x[0]] + 0.05 * centroid
        self._bounds = np.asarray(self.polygon.bounds).reshape(2, 2)

    # ------------------------------------------------------------ geometry
    def inside(self, pos: np.ndarray) -> np.ndarray:
        """Whether each point lies in the (closed) mode: ``(N, 2) -> (N,)`` bool."""
        return in_halfspaces(self.A, self.b, pos)

    def regions(self, pos: np.ndarray) -> np.ndarray:
        return self.inside(pos).astype(np.int64)

    def mode_of(self, pos: np.ndarray) -> np.ndarray:
        """Mode index of each point (0 inside, 1 outside): ``(N, 2) -> (N,)`` int."""
        return np.where(self.inside(pos), 0, 1).astype(np.int64)

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` starts inside the mode (see the class docstring); :class:`BoundExceeded` if sampling stalls."""
        n = integer(n, "n", low=0, owner="ConvexMode.sample_start")

        def draw(m: int) -> np.ndarray:
            if self.start_noise is None:
                return rng.uniform(self._bounds[0], self._bounds[1], size=(m, 2))
            t = rng.uniform(0.0, 1.0, size=(m, 1))
            cand = self.demo_start + t * (self.attractor - self.demo_start)
            return cand + rng.normal(0.0, self.start_noise, size=(m, 2))

        def failure(missing: int) -> str:
            return (
                f"ConvexMode: {missing} of {n} start states still outside the mode after "
                f"MAX_START_ROUNDS={MAX_START_ROUNDS} rounds of rejection sampling (start_noise={self.start_noise})"
            )

        return rejection_sample(draw, self.inside, n, 2, MAX_START_ROUNDS, failure)

    # ---------------------------------------------------------------- task
    def violates(self, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Leaving the mode (a push out of it is not the policy's move: :meth:`teleport` keeps the memory)."""
        return self.inside(prev_pos) & ~self.inside(pos)

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        inside = self.inside(pos)
        near = np.linalg.norm(np.asarray(pos) - self.attractor, axis=1) < self.attractor_radius
        return TaskReading(
            mode=np.where(inside, 0, 1).astype(np.int64),
            sensors=inside[:, None],
            success=inside & near & (memory[:, 0] == 0),
        )

    num_stages = 1

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage 1 at success, else 0; sub-goal = the attractor (the diagonal once the agent has left the mode)."""
        success = self.read(memory, pos).success
        distance = np.linalg.norm(np.asarray(pos, dtype=np.float64).reshape(-1, 2) - self.attractor, axis=1)
        failed = memory[:, 0] != 0
        distance = np.where(success, 0.0, np.where(failed, self.diagonal, distance))
        return success.astype(np.int64), distance

    def trajectory_success(self, xy: np.ndarray) -> bool:
        """The env's success rule on a whole path ``(T, 2)`` (e.g. a demo or a replay)."""
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) == 0:
            raise ValueError(f"xy must have shape (T>=1, 2), got {xy.shape}")
        inside = self.inside(xy)
        near = np.linalg.norm(xy - self.attractor, axis=1) < self.attractor_radius
        left = np.concatenate([[False], inside[:-1] & ~inside[1:]])
        reached = inside & near & ~np.logical_or.accumulate(left)
        return bool(reached.any())

    def draw(self, canvas: Canvas) -> None:
        canvas.polyline(np.vstack([self.vertices, self.vertices[:1]]), (60, 60, 60), thickness=2)
        radius = max(2, round(self.attractor_radius / (self.high[0] - self.low[0]) * canvas.width))
        canvas.disc(self.attractor, radius, (255, 140, 0))


class ConvexModeEnv(Kinematic2DEnv):
    """ConvexMode-v0 (TLI single-mode study); see the module docstring.

    Args:
        layout_seed: seed of the random convex mode (geometry only), an int >= 0.
        start_noise: ``None`` for uniform starts in the mode, or the std of the
            Gaussian noise added to demonstration-path points (TLI protocol), a
            real in ``[0, MAX_START_NOISE]``.
        terminate_on_violation: end the episode when the agent leaves the mode.
        dt, max_speed: integration step and speed limit (thesis: 0.01, 20).
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).
    >>> import gymnasium as gym
    >>> import numpy as np
    >>> import steer_envs
    >>> env = gym.make("steer_envs/ConvexMode-v0", layout_seed=3, start_noise=1.0)  # TLI's 5 % noise starts
    >>> obs, info = env.reset(seed=0)
    >>> model = env.unwrapped.model
    >>> info["mode_name"], info["success"], bool(np.linalg.norm(obs - model.attractor) > model.attractor_radius)
    ('inside', False, True)
    """

    def __init__(
        self,
        layout_seed: int = 0,
        start_noise: float | None = None,
        terminate_on_violation: bool = True,
        dt: float = 0.01,
        max_speed: float = 20.0,
        **options: Unpack[EnvOptions],
    ) -> None:
        super().__init__(
            ConvexModeModel(layout_seed=layout_seed, start_noise=start_noise),
            dt=dt,
            max_speed=max_speed,
            terminate_on_violation=terminate_on_violation,
            **options,
        )
        self.model: ConvexModeModel


make_vector_env = vector_factory(ConvexModeEnv)

__all__ = [
    "ATTRACTOR_RADIUS",
    "CONVEX_TASK",
    "MAX_START_NOISE",
    "ConvexModeEnv",
    "ConvexModeModel",
    "check_layout_seed",
    "convex_halfspaces",
    "in_halfspaces",
    "make_vector_env",
]
