"""Policies for GLiDE's 2D navigation study (thesis §4.2 "Mode-based motion generation", Table 4.1).

All policies are batched: ``act(states (N, 2)) -> velocities (N, 2)`` for the
``N`` agents of a vector env, and ``reset(mask)`` forgets the per-agent plan of
the agents whose episodes restart.

* :class:`BCPolicy` -- mode-agnostic behaviour cloning: one MLP ``pi(a | s)``
  fitted to every (state, action) pair of the successful demonstrations.
* :class:`GlideBCPolicy` -- GLiDE+BC: the mode classifier segments the demos,
  one BC MLP per mode, sequenced by the classifier's current mode, plus a
  pseudo-attractor (the mean state where the demos enter the next mode; in
  the final mode, the mean state where they end) that pulls the agent back
  toward the demonstrations when it is farther from the attractor than most
  demo states of its mode.
* :class:`GlidePlanningPolicy` -- GLiDE+Planning: a waypoint per mode (mean
  first-entry state of the mode in the segmented demos); from mode ``k`` the
  agent moves to the waypoint of mode ``k + 1`` staying inside the learned
  modes ``{k, k + 1}`` (the only transition it then makes is the allowed
  ``k -> k + 1``): a straight line where the learned modes allow it (always,
  inside a convex polygon that borders the next one), otherwise a path in
  the non-convex learned region (free space) -- by default the cheapest path
  on the learned grid under an *exposure* cost that grows near the learned
  boundaries of the forbidden modes (``PlannerConfig.free_space_planner=
  "costmap"``), or an RRT path as in the thesis (``"rrt"``) -- and an
  attractive/repulsive potential field when neither finds one. In the final mode it heads for
  the demos' goal (their mean last state) inside that mode, so a learned
  boundary short of the true one does not stop the agent early. Collision
  checks read the classifier's labels on a fine grid, computed once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage, sparse
from scipy.sparse.csgraph import dijkstra
from torch import nn

from steer_envs.baselines.glide.classifier import ModePredictor


# --------------------------------------------------------------------------------- BC
class _MLP(nn.Module):
    def __init__(self, dim_in: int, dim_out: int, hidden: Sequence[int]) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        last = dim_in
        for h in hidden:
            layers += [nn.Linear(last, h), nn.ReLU()]
            last = h
        layers.append(nn.Linear(last, dim_out))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


def _check_pairs(states: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = np.asarray(states, dtype=np.float32)
    a = np.asarray(actions, dtype=np.float32)
    if s.ndim != 2 or a.ndim != 2 or len(s) != len(a) or len(s) == 0:
        raise ValueError(f"states and actions must be (N, d) and (N, a) with N >= 1, got {s.shape} and {a.shape}")
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(a))):
        raise ValueError("states and actions must be finite")
    return s, a


@dataclass(frozen=True)
class BCConfig:
    """Training settings of the BC MLPs (Adam, MSE on actions scaled by ``max_speed``)."""

    hidden: tuple[int, ...] = (128, 128)
    steps: int = 1500
    batch_size: int = 256
    lr: float = 1e-3
    num_threads: int = 1

    def __post_init__(self) -> None:
        if self.num_threads < 1:
            raise ValueError(f"num_threads must be a positive int, got {self.num_threads!r}")
        if self.steps < 1 or self.batch_size < 1 or not self.hidden or min(self.hidden) < 1:
            raise ValueError("steps, batch_size and hidden sizes must be positive")
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive float, got {self.lr!r}")


class BCPolicy:
    """Behaviour cloning: an MLP from state to velocity, clipped to ``max_speed``.

    Args:
        states, actions: demonstration pairs ``(N, d)``, ``(N, 2)``.
        max_speed: the env's speed limit (actions are learned in units of it).
        seed: seeds the initial weights and the minibatches.
        config: training settings.
    """

    def __init__(
        self,
        states: np.ndarray,
        actions: np.ndarray,
        *,
        max_speed: float,
        seed: int = 0,
        config: BCConfig | None = None,
    ) -> None:
        s, a = _check_pairs(states, actions)
        if not (np.isfinite(max_speed) and max_speed > 0):
            raise ValueError(f"max_speed must be a positive float, got {max_speed!r}")
        self.config = config or BCConfig()
        self.max_speed = float(max_speed)
        self.mean = s.mean(0)
        self.scale = np.maximum(s.std(0), 1e-6)
        gen = torch.Generator().manual_seed(int(seed))
        torch_state = torch.random.get_rng_state()
        torch.manual_seed(int(seed))
        self.net = _MLP(s.shape[1], a.shape[1], self.config.hidden)
        torch.random.set_rng_state(torch_state)
        x = torch.from_numpy((s - self.mean) / self.scale)
        y = torch.from_numpy(a / self.max_speed)
        opt = torch.optim.Adam(self.net.parameters(), lr=self.config.lr)
        threads = torch.get_num_threads()
        torch.set_num_threads(self.config.num_threads)  # tiny nets: extra threads only spin
        try:
            for _ in range(self.config.steps):
                idx = torch.randint(0, len(x), (min(self.config.batch_size, len(x)),), generator=gen)
                loss = ((self.net(x[idx]) - y[idx]) ** 2).mean()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
        finally:
            torch.set_num_threads(threads)
        self.net.eval()

    @torch.no_grad()
    def act(self, states: np.ndarray) -> np.ndarray:
        """Velocities ``(N, 2)`` for states ``(N, d)`` (speed clipped to ``max_speed``)."""
        x = torch.from_numpy((np.asarray(states, dtype=np.float32) - self.mean) / self.scale)
        v = self.net(x).numpy().astype(np.float64) * self.max_speed
        return _clip_speed(v, self.max_speed)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Stateless: nothing to forget."""


def _clip_speed(v: np.ndarray, max_speed: float) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v * np.minimum(1.0, max_speed / np.maximum(norm, 1e-12))


# --------------------------------------------------------------------- segmentation
def segment_demonstrations(classifier: ModePredictor, demos: Sequence[np.ndarray], num_modes: int) -> list[np.ndarray]:
    """The classifier's mode of every state of every demo (``(T_i,)`` int arrays)."""
    if len(demos) == 0:
        raise ValueError("demos must not be empty")
    out = []
    for i, d in enumerate(demos):
        arr = np.asarray(d, dtype=np.float64)
        if arr.ndim != 2:
            raise ValueError(f"demos[{i}] must be (T, d), got {arr.shape}")
        modes = np.asarray(classifier.predict(arr), dtype=np.int64)
        if np.any((modes < 0) | (modes >= num_modes)):
            raise ValueError(f"classifier returned modes outside [0, {num_modes})")
        out.append(modes)
    return out


def mode_entry_points(demos: Sequence[np.ndarray], modes: Sequence[np.ndarray], num_modes: int) -> np.ndarray:
    """Mean first-entry state of each mode ``(K, d)`` over the demos (NaN where never entered).

    Row ``k`` is the mean of the first state of each demo that is in mode ``k``
    right after a state in another mode (GLiDE+Planning's waypoints; the
    pseudo-attractors of GLiDE+BC).
    """
    dim = np.asarray(demos[0]).shape[1]
    sums, counts = np.zeros((num_modes, dim)), np.zeros(num_modes)
    for d, m in zip(demos, modes, strict=True):
        d = np.asarray(d, dtype=np.float64)
        seen: set[int] = set()
        for t in range(1, len(m)):
            k = int(m[t])
            if m[t] != m[t - 1] and k not in seen:
                seen.add(k)
                sums[k] += d[t]
                counts[k] += 1
    out = np.full((num_modes, dim), np.nan)
    ok = counts > 0
    out[ok] = sums[ok] / counts[ok, None]
    return out


def mean_end_state(demos: Sequence[np.ndarray]) -> np.ndarray:
    """The mean of the demos' last states ``(d,)``: where they reach the goal (the final mode's target)."""
    return np.mean([np.asarray(d, dtype=np.float64)[-1] for d in demos], axis=0)


# --------------------------------------------------------------------------- GLiDE+BC
class GlideBCPolicy:
    """GLiDE+BC: per-mode BC policies chosen by the classifier, with pseudo-attractors.

    Args:
        classifier: the learned mode classifier.
        demos: demo states ``(T_i, d)``; actions: demo actions ``(T_i - 1, 2)``.
        num_modes: ``K``.
        max_speed: the env's speed limit.
        attractor_weight: ``w`` in ``(1 - w) pi_k(s) + w * (step toward the attractor)``.
        attractor_quantile: the attractor acts only beyond this quantile of the
            distances from mode ``k``'s demo states to its attractor.
        seed, config: BC training.
    """

    def __init__(
        self,
        classifier: ModePredictor,
        demos: Sequence[np.ndarray],
        actions: Sequence[np.ndarray],
        num_modes: int,
        *,
        max_speed: float,
        attractor_weight: float = 0.5,
        attractor_quantile: float = 0.9,
        seed: int = 0,
        config: BCConfig | None = None,
    ) -> None:
        if len(demos) != len(actions) or not demos:
            raise ValueError("demos and actions must be non-empty and of equal length")
        if not 0 <= attractor_weight <= 1:
            raise ValueError(f"attractor_weight must be in [0, 1], got {attractor_weight!r}")
        if not 0 < attractor_quantile <= 1:
            raise ValueError(f"attractor_quantile must be in (0, 1], got {attractor_quantile!r}")
        self.classifier = classifier
        self.num_modes = int(num_modes)
        self.max_speed = float(max_speed)
        self.attractor_weight = float(attractor_weight)
        modes = segment_demonstrations(classifier, demos, self.num_modes)
        entries = mode_entry_points(demos, modes, self.num_modes)
        goal = mean_end_state(demos)
        states = np.concatenate([np.asarray(d, dtype=np.float64)[:-1] for d in demos])
        acts = np.concatenate([np.asarray(a, dtype=np.float64) for a in actions])
        state_modes = np.concatenate([m[:-1] for m in modes])
        if len(states) != len(acts):
            raise ValueError("every demo needs T - 1 actions for its T states")
        self.policies: list[BCPolicy | None] = []
        self.attractors = np.full((self.num_modes, states.shape[1]), np.nan)
        self.thresholds = np.full(self.num_modes, np.inf)
        for k in range(self.num_modes):
            sel = state_modes == k
            self.policies.append(
                BCPolicy(states[sel], acts[sel], max_speed=max_speed, seed=seed + k, config=config)
                if sel.sum() >= 2
                else None
            )
            # mode k's attractor: where the demos enter mode k + 1; in the final mode, where they end
            target = entries[k + 1] if k + 1 < self.num_modes else goal
            if np.all(np.isfinite(target)):
                self.attractors[k] = target
                if sel.any():
                    dist = np.linalg.norm(states[sel] - target, axis=1)
                    self.thresholds[k] = float(np.quantile(dist, attractor_quantile))

    def act(self, states: np.ndarray) -> np.ndarray:
        x = np.asarray(states, dtype=np.float64)
        mode = np.asarray(self.classifier.predict(x), dtype=np.int64)
        out = np.zeros_like(x)
        for k in np.unique(mode):
            sel = mode == k
            policy = self.policies[k]
            v = policy.act(x[sel]) if policy is not None else np.zeros((int(sel.sum()), x.shape[1]))
            attractor = self.attractors[k]
            if np.all(np.isfinite(attractor)):
                delta = attractor - x[sel]
                dist = np.linalg.norm(delta, axis=1, keepdims=True)
                pull = delta / np.maximum(dist, 1e-12) * self.max_speed
                far = dist[:, 0] > self.thresholds[k]
                w = self.attractor_weight
                v[far] = (1 - w) * v[far] + w * pull[far]
                if policy is None:  # no demo states in this mode: the attractor alone
                    v = pull
            out[sel] = v
        return _clip_speed(out, self.max_speed)

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Stateless: the mode is read from the classifier at every step."""


# ---------------------------------------------------------------------- GLiDE+Planning
#: how GLiDE+Planning crosses free space: the exposure-weighted grid path (default) or the thesis's RRT
FREE_SPACE_PLANNERS: tuple[str, ...] = ("costmap", "rrt")


@dataclass(frozen=True)
class PlannerConfig:
    """GLiDE+Planning settings (glide.md: RRT 1000 iterations, 5% goal bias; fields k_att 1, k_rep 10, d0 0.8).

    ``rrt_step`` is 0.5 rather than the public 0.1: with 1000 iterations a
    0.1-step tree does not cross a 16 x 16 workspace; the path is still
    executed in env steps of at most ``max_speed``.

    ``clearance``: straight paths and RRT nodes keep this distance from the
    learned regions of the modes the agent may not enter (relaxed to the
    start's and the goal's own clearance when those are closer), the
    planning counterpart of the potential field's repulsion radius ``d0``:
    a learned boundary is only as sharp as the classifier, and a path that
    grazes it can clip a polygon corner labelled as free space. 0.5 was
    chosen on layouts 1-4 (not the Table 4.1 layout 0), 200 rollouts each:
    GLiDE+Planning success 0.986/0.905/0.942 (3/4/5 modes) with 0.3,
    0.992/0.965/0.975 with 0.5, 0.992/0.966/0.976 with 0.7, 0.994/0.976/0.979
    with 0.9 (perturbed 0.984/0.845/0.874 -> 0.991/0.935/0.940 with 0.5).

    ``free_space_planner``: ``"costmap"`` (default) crosses free space on the
    cheapest grid path under :meth:`LearnedModeMap.exposure` (``exposure_weight``
    ``W``, ``exposure_radius`` ``R``: a cell at distance ``d < R`` from a forbidden
    learned mode costs ``1 + W (1 - d/R)^2`` per unit length), string-pulled;
    ``"rrt"`` is the thesis's RRT (then straight-line shortcuts) with the hard
    ``clearance`` only. Why: the shortest safe-looking path hugs the learned
    boundary, and the learned boundary is wrong exactly where no data went --
    rounded polygon corners, the far side of the goal polygon -- so most
    failures were shortest paths clipping a corner by 0.5-1.5 units. W = 10,
    R = 2 were chosen on layouts 1-4 (300 rollouts each, the cached full-loss
    classifiers; means over layouts, unperturbed/perturbed for 3/4/5 modes):
    RRT 0.992/0.991, 0.965/0.935, 0.975/0.940; W 10 R 2 0.994/0.989,
    0.992/0.987, 0.978/0.937; W 30 R 2 0.994/0.990, 0.993/0.980, 0.978/0.939;
    W 3 R 2 0.992/0.988, 0.990/0.980, 0.978/0.930; W 10 R 3 0.992/0.990,
    0.991/0.960, 0.978/0.933 (a larger R detours so far that perturbed
    episodes run out of their 500 steps). With the 1000-step episodes of the
    Table 4.1 evaluation (no timeouts) the choice is a tie on layouts 1-4:
    W 10 R 2 0.994/0.989, 0.992/0.986, 0.978/0.929; W 10 R 3 0.992/0.991,
    0.991/0.979, 0.978/0.936; W 30 R 2 0.994/0.989, 0.993/0.980, 0.978/0.941;
    W 10 R 4 0.991/0.988, 0.989/0.983, 0.978/0.945 -- so the defaults stayed.
    """

    grid_resolution: float = 0.05
    rrt_iterations: int = 1000
    rrt_goal_bias: float = 0.05
    rrt_step: float = 0.5
    rrt_tolerance: float = 0.1
    rrt_restarts: int = 3
    k_att: float = 1.0
    k_rep: float = 10.0
    d0: float = 0.8
    check_spacing: float = 0.02
    waypoint_tolerance: float = 1e-6
    clearance: float = 0.5
    free_space_planner: str = "costmap"
    exposure_weight: float = 10.0
    exposure_radius: float = 2.0

    def __post_init__(self) -> None:
        if self.free_space_planner not in FREE_SPACE_PLANNERS:
            raise ValueError(
                f"free_space_planner must be one of {FREE_SPACE_PLANNERS}, got {self.free_space_planner!r}"
            )
        for name in ("exposure_weight", "exposure_radius"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite float >= 0, got {v!r}")
        for name in ("grid_resolution", "rrt_step", "rrt_tolerance", "k_att", "d0", "check_spacing"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive float, got {v!r}")
        if self.rrt_iterations < 1 or self.rrt_restarts < 1:
            raise ValueError("rrt_iterations and rrt_restarts must be positive")
        if not 0 <= self.rrt_goal_bias <= 1:
            raise ValueError(f"rrt_goal_bias must be in [0, 1], got {self.rrt_goal_bias!r}")
        if not (np.isfinite(self.clearance) and self.clearance >= 0):
            raise ValueError(f"clearance must be a float >= 0, got {self.clearance!r}")


class LearnedModeMap:
    """The classifier's mode labels on a fine grid: O(1) mode look-ups and distance fields."""

    def __init__(self, classifier: ModePredictor, low: np.ndarray, high: np.ndarray, resolution: float) -> None:
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.resolution = float(resolution)
        self.shape = tuple(
            int(np.ceil((h - lo) / self.resolution)) + 1 for lo, h in zip(self.low, self.high, strict=True)
        )
        xs = [self.low[i] + self.resolution * np.arange(self.shape[i]) for i in range(2)]
        gx, gy = np.meshgrid(xs[0], xs[1], indexing="ij")
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        self.labels = np.asarray(classifier.predict(pts), dtype=np.int64).reshape(self.shape)
        self._fields: dict[frozenset[int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._paths: dict[tuple[int, frozenset[int], float, float], tuple[np.ndarray, np.ndarray, int]] = {}
        self._exposures: dict[tuple[frozenset[int], float, float], np.ndarray] = {}

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ij = np.rint((np.asarray(points, dtype=np.float64) - self.low) / self.resolution).astype(np.int64)
        ij = np.clip(ij, 0, np.array(self.shape) - 1)
        return ij[..., 0], ij[..., 1]

    def mode(self, points: np.ndarray) -> np.ndarray:
        i, j = self.index(points)
        return self.labels[i, j]

    def inside(self, points: np.ndarray, allowed: frozenset[int]) -> np.ndarray:
        return np.isin(self.mode(points), list(allowed))

    def clearance(self, points: np.ndarray, allowed: frozenset[int]) -> np.ndarray:
        """Distance of each point to the nearest grid cell outside ``allowed`` (0 outside)."""
        dist = self.distance_field(allowed)[0]
        i, j = self.index(points)
        return dist[i, j]

    def segment_ok(
        self, a: np.ndarray, b: np.ndarray, allowed: frozenset[int], spacing: float, min_clearance: float = 0.0
    ) -> bool:
        """Whether the segment ``a -> b`` stays in ``allowed`` at least ``min_clearance`` from its outside."""
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts = a + t * (b - a)
        if min_clearance <= 0:
            return bool(np.all(self.inside(pts, allowed)))
        return bool(np.all(self.clearance(pts, allowed) >= min_clearance))

    def nearest_in(self, point: np.ndarray, mode: int) -> np.ndarray:
        """``point`` if the map labels it ``mode``, else the nearest grid point labelled ``mode``
        (``point`` itself when no cell has that label)."""
        p = np.asarray(point, dtype=np.float64)
        if self.mode(p[None])[0] == mode:
            return p
        cells = np.argwhere(self.labels == mode)
        if len(cells) == 0:
            return p
        pts = self.low + self.resolution * cells
        return pts[int(np.argmin(np.sum((pts - p) ** 2, axis=1)))]

    def distance_field(self, allowed: frozenset[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance to the nearest cell outside ``allowed`` and its gradient (cached)."""
        if allowed not in self._fields:
            inside = np.isin(self.labels, list(allowed))
            dist = ndimage.distance_transform_edt(inside) * self.resolution
            gi, gj = np.gradient(dist, self.resolution)
            self._fields[allowed] = (dist, gi, gj)
        return self._fields[allowed]

    def exposure(self, allowed: frozenset[int], weight: float, radius: float) -> np.ndarray:
        """Per-cell cost factor ``1 + weight * max(0, 1 - d / radius)^2``, ``d`` the distance to leaving ``allowed``.

        A classifier's boundary is least trustworthy where no data went (cut corners, the far side of a
        polygon): a path that keeps its distance from forbidden modes where it costs little to do so is
        robust to such errors, a path that grazes them (the shortest one) is not. Cached.
        """
        key = (allowed, float(weight), float(radius))
        if key not in self._exposures:
            dist = self.distance_field(allowed)[0]
            if radius <= 0 or weight <= 0:
                self._exposures[key] = np.ones_like(dist)
            else:
                self._exposures[key] = 1.0 + weight * np.clip(1.0 - dist / radius, 0.0, None) ** 2
        return self._exposures[key]

    def cost_to_go(
        self, goal: np.ndarray, allowed: frozenset[int], weight: float, radius: float
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Exposure-weighted shortest-path distances from every cell of ``allowed`` to ``goal``'s cell.

        Dijkstra (``scipy.sparse.csgraph``) on the 8-connected grid of the cells labelled ``allowed``,
        an edge costing its length times the mean :meth:`exposure` of its two cells. Returns the
        flat ``(distance, predecessor, goal_cell)`` arrays (predecessors point toward the goal);
        cached per (goal cell, allowed, weight, radius).
        """
        gi, gj = self.index(np.asarray(goal, dtype=np.float64)[None])
        h, w = self.shape
        source = int(gi[0] * w + gj[0])
        key = (source, allowed, float(weight), float(radius))
        if key not in self._paths:
            cost = self.exposure(allowed, weight, radius).ravel()
            ok = np.isin(self.labels, list(allowed)).ravel()
            idx = np.arange(h * w).reshape(h, w)
            rows, cols, vals = [], [], []
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                a = idx[: h - di, max(0, -dj) : w - max(0, dj)].ravel()
                b = idx[di:, max(0, dj) : w - max(0, -dj)].ravel()
                keep = ok[a] & ok[b]
                a, b = a[keep], b[keep]
                rows.append(a)
                cols.append(b)
                vals.append(np.hypot(di, dj) * self.resolution * 0.5 * (cost[a] + cost[b]))
            graph = sparse.csr_matrix(
                (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w, h * w)
            )
            dist, pred = dijkstra(graph, directed=False, indices=source, return_predecessors=True)
            self._paths[key] = (dist, pred, source)
        return self._paths[key]

    def shortest_path(
        self, start: np.ndarray, goal: np.ndarray, allowed: frozenset[int], weight: float, radius: float, spacing: float
    ) -> list[np.ndarray] | None:
        """The exposure-weighted shortest path ``start -> goal`` inside ``allowed`` (None: not connected).

        The grid path is shortened by string-pulling: from each point it jumps to the farthest later
        point whose straight segment stays inside ``allowed`` and is nowhere more exposed than the
        grid path between them, so the result is short without cutting closer to a forbidden mode.
        Returns the points after ``start``, ending with ``goal``.
        """
        dist, pred, source = self.cost_to_go(goal, allowed, weight, radius)
        w = self.shape[1]
        si, sj = self.index(np.asarray(start, dtype=np.float64)[None])
        cell = int(si[0] * w + sj[0])
        if not np.isfinite(dist[cell]):
            return None
        cells = []
        while cell != source:
            cell = int(pred[cell])
            cells.append(cell)
        # every 4th cell is enough to pull the string through (and 16x fewer segment checks)
        cells_ij = np.stack(np.divmod(np.asarray(cells[:-1][::4], dtype=np.int64), w), axis=1)
        ends = np.asarray([start, goal], dtype=np.float64)
        path = np.vstack([ends[:1], self.low + self.resolution * cells_ij, ends[1:]])
        exposure = self.exposure(allowed, weight, radius)

        def exposure_at(points: np.ndarray) -> np.ndarray:
            i, j = self.index(points)
            return exposure[i, j]

        along = exposure_at(path)
        out: list[np.ndarray] = []
        i = 0
        while i < len(path) - 1:
            j = len(path) - 1
            while j > i + 1:
                n = max(2, int(np.ceil(np.linalg.norm(path[j] - path[i]) / spacing)) + 1)
                points = path[i] + np.linspace(0.0, 1.0, n)[:, None] * (path[j] - path[i])
                if self.inside(points, allowed).all() and exposure_at(points).max() <= along[i : j + 1].max() + 1e-9:
                    break
                j -= 1
            out.append(path[j])
            i = j
        return out


def rrt(
    start: np.ndarray,
    goal: np.ndarray,
    valid_point: callable,  # type: ignore[valid-type]
    valid_segment: callable,  # type: ignore[valid-type]
    low: np.ndarray,
    high: np.ndarray,
    rng: np.random.Generator,
    *,
    iterations: int = 1000,
    goal_bias: float = 0.05,
    step: float = 0.5,
    tolerance: float = 0.1,
) -> list[np.ndarray] | None:
    """Rapidly-exploring random tree from ``start`` to within ``tolerance`` of ``goal`` (None if not found).

    Returns the path ``[start, ..., goal]`` after greedy shortcutting.
    """
    nodes = [np.asarray(start, dtype=np.float64)]
    parents = [-1]
    pts = np.empty((iterations + 1, len(start)))
    pts[0] = nodes[0]
    goal = np.asarray(goal, dtype=np.float64)
    found = -1
    if valid_segment(nodes[0], goal):
        return [nodes[0], goal]
    for _ in range(iterations):
        target = goal if rng.random() < goal_bias else rng.uniform(low, high)
        near = int(np.argmin(np.sum((pts[: len(nodes)] - target) ** 2, axis=1)))
        delta = target - nodes[near]
        dist = float(np.linalg.norm(delta))
        if dist < 1e-9:
            continue
        new = nodes[near] + delta * min(1.0, step / dist)
        if not (valid_point(new) and valid_segment(nodes[near], new)):
            continue
        pts[len(nodes)] = new
        nodes.append(new)
        parents.append(near)
        if np.linalg.norm(new - goal) <= tolerance or valid_segment(new, goal):
            found = len(nodes) - 1
            break
    if found < 0:
        return None
    path = [goal]
    k = found
    while k >= 0:
        path.append(nodes[k])
        k = parents[k]
    path.reverse()
    # greedy shortcut: from each point jump to the farthest directly reachable one
    short = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not valid_segment(path[i], path[j]):
            j -= 1
        short.append(path[j])
        i = j
    return short


class GlidePlanningPolicy:
    """GLiDE+Planning over the learned modes (see the module docstring).

    Args:
        classifier: the learned mode classifier.
        demos: demo states (segmented by the classifier for the waypoints).
        num_modes: ``K``.
        low, high: workspace corners.
        max_speed: the env's speed limit (one env step moves at most this far).
        seed: seeds the RRT.
        config: planner settings.
    """

    def __init__(
        self,
        classifier: ModePredictor,
        demos: Sequence[np.ndarray],
        num_modes: int,
        *,
        low: np.ndarray,
        high: np.ndarray,
        max_speed: float,
        seed: int = 0,
        config: PlannerConfig | None = None,
    ) -> None:
        self.config = config or PlannerConfig()
        self.num_modes = int(num_modes)
        self.max_speed = float(max_speed)
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.map = LearnedModeMap(classifier, self.low, self.high, self.config.grid_resolution)
        modes = segment_demonstrations(classifier, demos, self.num_modes)
        self.waypoints = mode_entry_points(demos, modes, self.num_modes)
        # a mode the demos never entered (a wrong plan, a poor classifier): aim at the demos' end
        ends = mean_end_state(demos)
        for k in range(1, self.num_modes):
            if not np.all(np.isfinite(self.waypoints[k])):
                self.waypoints[k] = ends
            # the mean of entry points can fall outside a curved learned region: an agent would reach it
            # still in mode k - 1 and stop there; aim at the nearest point the classifier labels k instead
            self.waypoints[k] = self.map.nearest_in(self.waypoints[k], k)
        #: where the demos end (the mean of their last states): the target inside the final mode, so an
        #: agent that the classifier already places in the final mode still walks into the demos' goal
        #: region instead of stopping on a learned boundary that lies short of the true one
        self.goal = ends
        self.rng = np.random.default_rng(seed)
        self._plans: list[list[np.ndarray]] = []
        self._plan_mode: np.ndarray = np.zeros(0, dtype=np.int64)
        self._expected: np.ndarray = np.zeros((0, 2))
        self.stats = {"straight": 0, "costmap": 0, "rrt": 0, "field": 0}

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Forget the plans of the agents in ``mask`` (all when None)."""
        if mask is None:
            self._plans = []
            return
        for i in np.flatnonzero(np.asarray(mask, dtype=bool)):
            if i < len(self._plans):
                self._plans[i] = []
                self._plan_mode[i] = -1

    def _target(self, mode: int) -> tuple[np.ndarray, frozenset[int]]:
        """The point an agent in ``mode`` heads for and the learned modes it may cross on the way."""
        if mode >= self.num_modes - 1:
            return self.goal, frozenset({self.num_modes - 1})
        return self.waypoints[mode + 1], frozenset({mode, mode + 1})

    def _plan(self, x: np.ndarray, mode: int) -> list[np.ndarray]:
        goal, allowed = self._target(mode)
        cfg = self.config
        if mode == 0 and cfg.free_space_planner == "costmap":
            path = self.map.shortest_path(x, goal, allowed, cfg.exposure_weight, cfg.exposure_radius, cfg.check_spacing)
            if path is not None:
                self.stats["costmap"] += 1
                return path
            # no grid path inside the allowed learned modes (a poor map): the RRT below still tries (on layouts
            # 1-4 going straight to the potential field instead cost 5-mode perturbed success 0.937 -> 0.927)
        # the clearance the path keeps: the configured one, or less where the start or the goal is closer
        # (a cell inside ``allowed`` is at least one cell from its outside: below that, only stay inside)
        margin = min(cfg.clearance, float(self.map.clearance(np.stack([x, goal]), allowed).min()))
        if margin <= self.map.resolution:
            margin = 0.0

        def seg(a: np.ndarray, b: np.ndarray) -> bool:
            return self.map.segment_ok(a, b, allowed, cfg.check_spacing, margin)

        if seg(x, goal):
            self.stats["straight"] += 1
            return [goal]
        for _ in range(cfg.rrt_restarts):
            path = rrt(
                x,
                goal,
                lambda p: bool(self.map.clearance(p[None, :], allowed)[0] >= max(margin, 1e-9)),
                seg,
                self.low,
                self.high,
                self.rng,
                iterations=cfg.rrt_iterations,
                goal_bias=cfg.rrt_goal_bias,
                step=cfg.rrt_step,
                tolerance=cfg.rrt_tolerance,
            )
            if path is not None:
                self.stats["rrt"] += 1
                return path[1:]
        self.stats["field"] += 1
        return []  # potential field

    def _field_step(self, x: np.ndarray, mode: int) -> np.ndarray:
        goal, allowed = self._target(mode)
        dist, gi, gj = self.map.distance_field(allowed)
        i, j = self.map.index(x[None, :])
        d = float(dist[i[0], j[0]])
        grad = np.array([gi[i[0], j[0]], gj[i[0], j[0]]])
        force = self.config.k_att * (goal - x)
        cfg = self.config
        if 0 < d < cfg.d0:
            force += cfg.k_rep * (1.0 / d - 1.0 / cfg.d0) / d**2 * grad
        return force

    def act(self, states: np.ndarray) -> np.ndarray:
        x = np.asarray(states, dtype=np.float64)
        n = len(x)
        if len(self._plans) != n:
            self._plans = [[] for _ in range(n)]
            self._plan_mode = np.full(n, -1, dtype=np.int64)
            self._expected = x.copy()
        modes = self.map.mode(x)
        out = np.zeros_like(x)
        jumped = np.linalg.norm(x - self._expected, axis=1) > self.max_speed + 1e-6
        for i in range(n):
            m = int(modes[i])
            if self._plan_mode[i] != m or jumped[i]:  # new mode, or pushed: plan again
                self._plans[i] = self._plan(x[i], m)
                self._plan_mode[i] = m
            plan = self._plans[i]
            while plan and np.linalg.norm(plan[0] - x[i]) <= self.config.waypoint_tolerance:
                plan.pop(0)
            out[i] = plan[0] - x[i] if plan else self._field_step(x[i], m)
        out = _clip_speed(out, self.max_speed)
        self._expected = x + out
        return out


__all__ = [
    "BCConfig",
    "BCPolicy",
    "GlideBCPolicy",
    "GlidePlanningPolicy",
    "LearnedModeMap",
    "PlannerConfig",
    "mean_end_state",
    "mode_entry_points",
    "rrt",
    "segment_demonstrations",
]
