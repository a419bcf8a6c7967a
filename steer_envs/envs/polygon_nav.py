"""PolygonNav-{3,4,5}Mode-v0: traverse a chain of random convex polygons (GLiDE 2D navigation).

Thesis §4.3 "2D Navigation": mode 0 is the free space, modes ``1..K-1`` are a
chain of random convex quadrilaterals, consecutive ones sharing a full edge.
The agent starts in free space and must reach the last polygon, crossing the
chain in order. Allowed mode transitions: self-loops, ``i -> i+1``,
``i+1 -> i`` and any polygon back to free space; anything else (e.g. free space
straight into polygon 2) is an invalid transition: a constraint violation that
ends the episode. Dynamics (public GLiDE code): single integrator whose step
is the action with its length clipped to 0.1 (``dt = 1``, ``max_speed = 0.1``),
500 steps per episode (``gym.make(..., max_episode_steps=...)`` changes it).

Geometry (after the public GLiDE generator): each polygon is a random convex
quadrilateral scaled to the unit box; polygon ``j+1`` is attached by the
orientation-preserving similarity that maps its first edge ``(v0, v1)`` onto
polygon ``j``'s last edge ``(v2, v3)`` (reversed, so it lies on the other side);
coordinates are then scaled ``x5 - 4``. "Last edge" is read as the last edge of
the open vertex list, opposite the first edge, so a polygon's two shared edges
never meet at a vertex and non-consecutive polygons stay apart. Unlike the
public generator, a layout is redrawn (deterministically, from the layout rng)
until every polygon lies ``workspace_margin`` inside ``[-8, 8]^2``,
non-consecutive polygons are at least ``min_gap`` apart, and each polygon has
area >= 1; the union of the chain is then a disk away from the walls, so the
free space is connected.

Description
    See above; the mode names (``task.modes``) are descriptive already.

Observation
    ``Box(float32)``: the agent's ``(x1, x2)`` in the workspace (``x1`` right, ``x2`` up, as plotted);
    with ``observe_sensors=True`` followed by the sensor APs ``in_p1``, ``in_p2``, ... as 0/1.

Action
    ``Box(-0.1, 0.1, (2,), float32)``: a velocity, ``x' = x + 1 u`` with ``|u|`` clipped to 0.1;
    ``normalize_actions=True``: ``[-1, 1]^2``, scaled by 0.1.

Rewards
    ``reward_type="sparse"`` (default) or ``"dense"``, as in every 2D env
    (:class:`~steer_envs.envs.kinematic.Kinematic2DEnv`); the dense potential's stage = the mode (free 0, polygon j =
    j), sub-goal = polygon 1's centroid from free space (its distance measured along the shortest path around the later
    polygons, :mod:`~steer_envs.envs.geodesic`), then a point 0.2 past the middle of the edge shared with the next
    polygon (``phi = -1`` after an invalid transition).

Termination
    On success (in the last polygon with no invalid transition) and, with the default
    ``terminate_on_violation=True``, on an invalid transition; truncation at 500 steps (registered).

Registered ids
    ``steer_envs/PolygonNav-{3,4,5}Mode-v0`` (``num_modes`` 3, 4, 5) and
    ``steer_envs/PolygonNav-{3,4,5}ModeDense-v0`` (for RL: ``reward_type="dense"``,
    ``observe_sensors=True``, ``normalize_actions=True``).
"""

from __future__ import annotations

import functools
from typing import Unpack

import numpy as np
from shapely.geometry import MultiPoint, Polygon, box
from shapely.geometry.polygon import orient
from shapely.ops import unary_union

from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import BoundExceeded, integer, real_scalar
from steer_envs.envs.convex_mode import check_layout_seed, convex_halfspaces, in_halfspaces
from steer_envs.envs.geodesic import GeodesicDistance
from steer_envs.envs.kinematic import EnvOptions, Kinematic2DEnv, TaskReading, ViolationLatchModel
from steer_envs.envs.kinematic_vector import vector_factory
from steer_envs.envs.render import Canvas

WORKSPACE_HALF_WIDTH = 8.0
#: unit-box coordinates map to the workspace by ``x * SCALE + OFFSET`` (public code: x5 - 4).
SCALE, OFFSET = 5.0, -4.0
MIN_POLYGON_AREA = 1.0
#: shape limits of a random quadrilateral in unit-box coordinates (keeps polygons navigable).
_MIN_ANGLE_DEG, _MAX_ANGLE_DEG, _MIN_EDGE, _MIN_UNIT_AREA = 30.0, 150.0, 0.3, 0.3
#: draws of whole polygon chains before a layout is given up (a valid one takes a handful).
MAX_LAYOUT_TRIES = 100_000
#: draws of 4 random points per quadrilateral before giving up (about one in five is accepted).
MAX_QUAD_TRIES = 10_000
#: rounds of rejection sampling in :meth:`PolygonNavModel.sample_in_mode` (each redraws every rejected point).
MAX_SAMPLE_ROUNDS = 10_000


def polygon_nav_task(num_modes: int) -> TaskSpec:
    """The TaskSpec of a ``num_modes`` chain: modes ``free, p1, ..., p{K-1}``.

    One sensor AP per polygon (``in_p1``, ...), true while the agent is in that
    polygon; no AP true means free space.
    """
    polys = tuple(f"p{j}" for j in range(1, num_modes))
    modes = ("free", *polys)
    transitions = {(modes[i], modes[i + 1]) for i in range(num_modes - 1)}
    transitions |= {(modes[i + 1], modes[i]) for i in range(num_modes - 1)}
    transitions |= {(p, "free") for p in polys}
    sensor_modes = {frozenset(): "free", **{frozenset({f"in_{p}"}): p for p in polys}}
    return TaskSpec(
        name=f"PolygonNav-{num_modes}Mode",
        modes=modes,
        sensors=tuple(f"in_{p}" for p in polys),
        sensor_modes=sensor_modes,
        transitions=frozenset(transitions),
        initial="free",
        goal=(modes[-1],),
    )


def _random_quad(rng: np.random.Generator) -> np.ndarray:
    """A random convex quadrilateral scaled to the unit box, CCW vertices ``(4, 2)``."""
    for _ in range(MAX_QUAD_TRIES):
        pts = rng.uniform(0.0, 1.0, size=(4, 2))
        hull = MultiPoint([tuple(p) for p in pts]).convex_hull
        if not isinstance(hull, Polygon):
            continue
        v = np.asarray(orient(hull, sign=1.0).exterior.coords, dtype=np.float64)[:-1]
        if len(v) != 4:
            continue
        v = (v - v.min(axis=0)) / (v.max(axis=0) - v.min(axis=0))
        edges = np.roll(v, -1, axis=0) - v
        prev_edges = -np.roll(edges, 1, axis=0)
        cos = np.einsum("ij,ij->i", edges, prev_edges) / (
            np.linalg.norm(edges, axis=1) * np.linalg.norm(prev_edges, axis=1)
        )
        angles = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        if (
            angles.min() >= _MIN_ANGLE_DEG
            and angles.max() <= _MAX_ANGLE_DEG
            and np.linalg.norm(edges, axis=1).min() >= _MIN_EDGE
            and Polygon(v).area >= _MIN_UNIT_AREA
        ):
            return v
    raise BoundExceeded(  # pragma: no cover - about one draw in five is accepted
        f"PolygonNav: no acceptable random quadrilateral in MAX_QUAD_TRIES={MAX_QUAD_TRIES} draws"
    )


def _attach(prev: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Map ``new``'s first edge (v0, v1) onto ``prev``'s last edge (v2, v3), reversed."""
    q2, q3 = prev[2], prev[3]
    a = complex(*(q2 - q3)) / complex(*(new[1] - new[0]))
    z = (new[:, 0] + 1j * new[:, 1] - complex(*new[0])) * a + complex(*q3)
    out = np.stack([z.real, z.imag], axis=1)
    out[0], out[1] = q3, q2  # share the edge exactly, not up to rounding
    return out


class PolygonNavModel(ViolationLatchModel):
    """Batched task physics of PolygonNav (a chain of ``num_modes - 1`` polygons).

    Public geometry (fixed by ``layout_seed``; polygon ``j`` of the task is index
    ``j - 1`` below):
        vertices: tuple of ``(4, 2)`` CCW vertex arrays; polygon ``j``'s edge
            ``(v2, v3)`` is polygon ``j+1``'s edge ``(v1, v0)``.
        polygons: the same as shapely ``Polygon`` objects.
        A, b: stacked half-space forms, ``(P, 4, 2)`` and ``(P, 4)``: ``x`` is in
            polygon ``j`` iff ``A[j-1] @ x <= b[j-1]``.
        shared_edges: ``(P - 1, 2, 2)`` endpoints of the edge between polygons
            ``j`` and ``j+1``.
        union: shapely union of the polygons; free_space: the workspace minus it.
        allowed: ``(K, K)`` bool matrix of allowed mode transitions.

    Mode of a point: the polygon containing it (closed sets; on a shared edge
    the later polygon wins), else 0 (free space). Task memory (1 slot):
    whether an invalid transition was ever made by a step. Success: in the last
    polygon with no invalid transition. External pushes (``perturb``) do not
    count as transitions of the agent.
    """

    memory_size = 1

    def __init__(
        self,
        num_modes: int = 4,
        layout_seed: int = 0,
        *,
        workspace_margin: float = 0.5,
        min_gap: float = 0.5,
    ) -> None:
        owner = "PolygonNav"
        # num_modes in [2, 9]: free space + 1..8 polygons
        self.num_modes = integer(num_modes, "num_modes", low=2, high=9, owner=owner)
        self.num_polygons = self.num_modes - 1
        self.num_stages = self.num_polygons  # mode advances from free space to the last polygon
        self.layout_seed = check_layout_seed(layout_seed, owner)
        self.workspace_margin = real_scalar(
            workspace_margin, "workspace_margin", low=0.0, high=2.0, high_inclusive=False, owner=owner
        )
        self.min_gap = real_scalar(
            min_gap, "min_gap", low=0.0, high=4.0, low_inclusive=False, high_inclusive=False, owner=owner
        )
        self.task = polygon_nav_task(self.num_modes)
        self.low = np.full(2, -WORKSPACE_HALF_WIDTH)
        self.high = np.full(2, WORKSPACE_HALF_WIDTH)
        self.region_names = self.task.modes

        verts = self._generate(np.random.default_rng(self.layout_seed))
        self.vertices: tuple[np.ndarray, ...] = tuple(verts)
        self.polygons: tuple[Polygon, ...] = tuple(Polygon(v) for v in verts)
        halfspaces = [convex_halfspaces(v) for v in verts]
        self.A = np.stack([h[0] for h in halfspaces])
        self.b = np.stack([h[1] for h in halfspaces])
        self.shared_edges = np.array([[v[2], v[3]] for v in verts[:-1]]).reshape(-1, 2, 2)
        self.union = unary_union(self.polygons)
        self.free_space = box(-WORKSPACE_HALF_WIDTH, -WORKSPACE_HALF_WIDTH, WORKSPACE_HALF_WIDTH, WORKSPACE_HALF_WIDTH)
        self.free_space = self.free_space.difference(self.union)
        self.allowed = self.task.allowed_matrix()
        centroids = np.array([np.asarray(p.centroid.coords[0]) for p in self.polygons])
        mids = self.shared_edges.mean(axis=1)  # (P - 1, 2)
        inward = centroids[1:] - mids
        past_edges = mids + 0.2 * inward / np.linalg.norm(inward, axis=1, keepdims=True)
        #: dense-reward sub-goal of each mode but the last: polygon 1's centroid, then just past each shared edge
        self.subgoals = np.concatenate([centroids[:1], past_edges]).reshape(-1, 2)

    @functools.cached_property
    def free_distance(self) -> GeodesicDistance:
        """Free space's way to polygon 1's centroid around the later polygons (entering them is a
        violation); built on first use, by the dense reward."""
        return GeodesicDistance(self.vertices[1:], self.subgoals[0])

    def _generate(self, rng: np.random.Generator) -> list[np.ndarray]:
        lim = WORKSPACE_HALF_WIDTH - self.workspace_margin
        for _ in range(MAX_LAYOUT_TRIES):
            unit = [_random_quad(rng)]
            for _ in range(self.num_polygons - 1):
                unit.append(_attach(unit[-1], _random_quad(rng)))
            verts = [u * SCALE + OFFSET for u in unit]
            stacked = np.vstack(verts)
            if stacked.min() < -lim or stacked.max() > lim:
                continue
            polys = [Polygon(v) for v in verts]
            if min(p.area for p in polys) < MIN_POLYGON_AREA:
                continue
            if any(
                polys[i].distance(polys[j]) < self.min_gap for i in range(len(polys)) for j in range(i + 2, len(polys))
            ):
                continue
            return verts
        raise BoundExceeded(  # pragma: no cover - a valid layout takes a handful of draws
            f"PolygonNav: no valid layout in MAX_LAYOUT_TRIES={MAX_LAYOUT_TRIES} draws (num_modes={self.num_modes}, "
            f"workspace_margin={self.workspace_margin}, min_gap={self.min_gap})"
        )

    # ------------------------------------------------------------ geometry
    def contains(self, pos: np.ndarray) -> np.ndarray:
        """Membership of each point in each (closed) polygon: ``(N, 2) -> (N, P)`` bool."""
        return in_halfspaces(self.A, self.b, pos)

    def mode_of(self, pos: np.ndarray) -> np.ndarray:
        """Mode index of each point: ``(N, 2) -> (N,)`` int (0 = free space)."""
        inside = self.contains(pos)
        last = self.num_polygons - np.argmax(inside[:, ::-1], axis=1)
        return np.where(inside.any(axis=1), last, 0).astype(np.int64)

    def regions(self, pos: np.ndarray) -> np.ndarray:
        return self.mode_of(pos)

    def sample_start(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Uniform in free space (rejection sampling in the workspace)."""
        return self.sample_in_mode(rng, n, 0)

    def sample_in_mode(self, rng: np.random.Generator, n: int, mode: int) -> np.ndarray:
        """``n`` points uniform in the region of ``mode`` (0: free space), by rejection sampling in
        the workspace (free space) or in the polygon's bounding box.

        ``n`` is an int >= 0, ``mode`` an int in ``[0, num_modes)``; rejection
        sampling that leaves points unplaced after :data:`MAX_SAMPLE_ROUNDS`
        rounds raises :class:`~steer_envs.core.validation.BoundExceeded`.
        """
        n = integer(n, "n", low=0, owner="PolygonNav.sample_in_mode")
        mode = integer(mode, "mode", low=0, high=self.num_modes - 1, owner="PolygonNav.sample_in_mode")
        lo, hi = np.asarray(self.low, dtype=np.float64), np.asarray(self.high, dtype=np.float64)
        if mode > 0:
            bounds = np.asarray(self.polygons[mode - 1].bounds, dtype=np.float64)
            lo, hi = np.maximum(lo, bounds[:2]), np.minimum(hi, bounds[2:])
        out = np.empty((n, 2))
        todo = np.arange(n)
        for _ in range(MAX_SAMPLE_ROUNDS):
            if not len(todo):
                return out
            cand = rng.uniform(lo, hi, size=(len(todo), 2))
            ok = self.mode_of(cand) == mode
            out[todo[ok]] = cand[ok]
            todo = todo[~ok]
        if not len(todo):
            return out
        raise BoundExceeded(
            f"PolygonNav.sample_in_mode: {len(todo)} of {n} points still outside mode {mode} after "
            f"MAX_SAMPLE_ROUNDS={MAX_SAMPLE_ROUNDS} rounds of rejection sampling"
        )

    # ---------------------------------------------------------------- task
    def violates(self, prev_pos: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """A mode change the task does not allow (a push is not the agent's transition: the memory is kept)."""
        return ~self.allowed[self.mode_of(prev_pos), self.mode_of(pos)]

    def read(self, memory: np.ndarray, pos: np.ndarray) -> TaskReading:
        mode = self.mode_of(pos)
        sensors = mode[:, None] == np.arange(1, self.num_modes)[None, :]
        return TaskReading(mode=mode, sensors=sensors, success=(mode == self.num_modes - 1) & (memory[:, 0] == 0))

    def progress(self, memory: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stage = the mode; sub-goal = polygon 1's centroid from free space (measured along the shortest
        path around the later polygons, :attr:`free_distance`), then a point 0.2 past the middle of the
        edge shared with the next polygon (the diagonal after an invalid transition)."""
        mode = self.mode_of(pos)
        failed = memory[:, 0] != 0
        goal = self.subgoals[np.minimum(mode, self.num_modes - 2)]
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        distance = np.linalg.norm(p - goal, axis=1)
        free = mode == 0
        if free.any():
            distance[free] = self.free_distance(p[free])
        done = mode == self.num_modes - 1
        distance = np.where(failed, self.diagonal, np.where(done, 0.0, distance))
        return np.where(failed, 0, mode), distance

    def trajectory_success(self, xy: np.ndarray) -> bool:
        """GLiDE's success check on a whole path ``(T, 2)``: every transition allowed up to
        reaching the last polygon (used to label demonstration replays)."""
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) == 0:
            raise ValueError(f"xy must have shape (T>=1, 2), got {xy.shape}")
        modes = self.mode_of(xy)
        bad = np.concatenate([[False], ~self.allowed[modes[:-1], modes[1:]]])
        reached = (modes == self.num_modes - 1) & ~np.logical_or.accumulate(bad)
        return bool(reached.any())

    def draw(self, canvas: Canvas) -> None:
        for v in self.vertices:
            canvas.polyline(np.vstack([v, v[:1]]), (60, 60, 60), thickness=1)


class PolygonNavEnv(Kinematic2DEnv):
    """PolygonNav-kMode-v0 (GLiDE 2D navigation); see the module docstring.

    Args:
        num_modes: number of modes K (free space + K-1 polygons), an int in [2, 9]; registered 3, 4, 5.
        layout_seed: seed of the random polygon chain (geometry only), an int >= 0.
        terminate_on_violation: end the episode on an invalid transition (GLiDE: yes), a bool.
        workspace_margin, min_gap: layout validity margins (see the module docstring), reals in
            ``[0, 2)`` and ``(0, 4)``.
        render_mode, render_size, reward_type, observe_sensors, normalize_actions: the options of every 2D env
            (:class:`~steer_envs.envs.kinematic.EnvOptions`, see :class:`~steer_envs.envs.kinematic.Kinematic2DEnv`).
    >>> import gymnasium as gym
    >>> import steer_envs
    >>> env = gym.make("steer_envs/PolygonNav-4Mode-v0", layout_seed=0)
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.task.modes, info["mode_name"]
    (('free', 'p1', 'p2', 'p3'), 'free')
    """

    def __init__(
        self,
        num_modes: int = 4,
        layout_seed: int = 0,
        terminate_on_violation: bool = True,
        workspace_margin: float = 0.5,
        min_gap: float = 0.5,
        **options: Unpack[EnvOptions],
    ) -> None:
        super().__init__(
            PolygonNavModel(num_modes, layout_seed, workspace_margin=workspace_margin, min_gap=min_gap),
            dt=1.0,
            max_speed=0.1,
            terminate_on_violation=terminate_on_violation,
            **options,
        )
        self.model: PolygonNavModel


make_vector_env = vector_factory(PolygonNavEnv)

__all__ = [
    "MAX_LAYOUT_TRIES",
    "MAX_QUAD_TRIES",
    "MAX_SAMPLE_ROUNDS",
    "PolygonNavEnv",
    "PolygonNavModel",
    "make_vector_env",
    "polygon_nav_task",
]
