"""The closed-loop controllers a person pushes in steer-ui, and what the page draws of each.

A :class:`Controller` acts from the env's observation and info at every step
and describes itself to the page: overlays in the view's pixels
(:meth:`Controller.overlays`) and rows of text (:meth:`Controller.panel`).

* ``"ltl-ds"`` (:class:`LTLDSController`, TLI): SoupScoop's LTL-DS policy
  (:func:`~steer_envs.baselines.lpv_ds.task_policies.soup_scoop_policy`: one
  LPV-DS per mode under the soup-scooping automaton, with modulation by cuts
  learned from invariance failures). Drawn: the current mode's flow field, the
  learned cuts and the attractor; shown: the automaton's mode and plan, the
  mode sensors, and each mode change (planned, push, invariance failure) with
  whether a push skipped or undid a mode.
* ``"glide-planning"`` (:class:`GlideController`, GLiDE): GLiDE+Planning over
  the modes a classifier learned from success labels
  (:func:`~steer_envs.baselines.glide.polygon.make_polygon_policy`). Drawn: the
  learned mode map and the path being followed; shown: the learned mode beside
  the true one.

Fitted policies and trained classifiers are kept per process (a classifier
also on disk, under ``cache_dir``); each session gets its own copy, so cuts
learned in one tab stay in it.
"""

from __future__ import annotations

import base64
import copy
import io
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.ui.views import PixelMap, PlaneView

#: the views a push session draws in: a kinematic env's top-down box, or a robosuite camera's drag plane
PushView = PixelMap | PlaneView

__all__ = [
    "DEFAULT_CACHE_DIR",
    "Controller",
    "GlideController",
    "LTLDSController",
    "mode_map_png",
    "quick_glide_setup",
]

#: where trained GLiDE classifiers are kept between runs (``steer-ui --cache-dir`` overrides)
DEFAULT_CACHE_DIR = Path.home() / ".cache" / "steer-envs" / "ui"
#: flow arrows per side of the view
FLOW_GRID = 15
#: RGBA tints of learned modes on the map (free space first; mode k uses row k mod len)
MODE_TINTS = np.array(
    [[0, 0, 0, 0], [27, 158, 119, 110], [217, 95, 2, 110], [117, 112, 179, 110], [231, 41, 138, 110],
     [102, 166, 30, 110]],
    dtype=np.uint8,
)  # fmt: skip

_CACHE: dict[tuple[Any, ...], Any] = {}
_CACHE_LOCK = threading.Lock()


def _cached(key: tuple[Any, ...], build: Callable[[], Any]) -> Any:
    """``build()`` once per ``key`` in this process (serialized), then a deep copy per caller."""
    with _CACHE_LOCK:
        if key not in _CACHE:
            _CACHE[key] = build()
        return copy.deepcopy(_CACHE[key])


def _png_data_url(rgba: np.ndarray) -> str:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(rgba, mode="RGBA").save(buffer, format="PNG", compress_level=1)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def mode_map_png(modes: np.ndarray) -> str:
    """An ``(H, W)`` int mode map as a translucent RGBA PNG data URL (free space clear, modes tinted).

    >>> mode_map_png(np.zeros((2, 2), dtype=int)).startswith("data:image/png;base64,")
    True
    """
    labels = np.asarray(modes, dtype=np.int64)
    return _png_data_url(MODE_TINTS[np.mod(labels, len(MODE_TINTS))])


def _round(pixels: np.ndarray) -> list[Any]:
    return np.round(np.asarray(pixels, dtype=np.float64), 1).tolist()  # type: ignore[no-any-return]


class Controller(ABC):
    """Acts on the env every step; tells the page what to draw and show."""

    @abstractmethod
    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        """A new episode starts at ``obs``."""

    @abstractmethod
    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """The action for this step."""

    def observe(self, obs: Any, info: dict[str, Any]) -> None:  # noqa: B027 - optional hook
        """A reading without acting: after a push (``info`` is ``perturb``'s) or at the episode's end."""

    def agent(self, base: Any) -> np.ndarray:
        """Where the agent is, in the coordinates the view draws (default: a kinematic env's ``state[:2]``)."""
        return np.asarray(base.state, dtype=np.float64)[:2].copy()

    def push_target(self, base: Any, point: np.ndarray) -> np.ndarray:
        """The ``perturb(to=...)`` argument that puts the agent at view point ``point`` (default: ``point``)."""
        return point

    @abstractmethod
    def overlays(self, view: PushView, state: np.ndarray, full: bool) -> dict[str, Any]:
        """Overlay name -> data in ``view``'s pixels (``full``: also the ones that do not change per step)."""

    @abstractmethod
    def panel(self, state: np.ndarray, info: dict[str, Any]) -> list[tuple[str, str]]:
        """``(label, value)`` rows for the page about the agent at ``state`` (``info``: the env's latest)."""


# ------------------------------------------------------------------ TLI: LTL-DS
def _jump(gap: int) -> str:
    """What a mode change of ``gap`` places along the task's mode order did.

    >>> _jump(2), _jump(1), _jump(-1)
    ('skipped a mode', 'advanced a mode', 'undid a mode')
    """
    if gap > 1:
        return "skipped a mode"
    if gap == 1:
        return "advanced a mode"
    return "undid a mode" if gap < 0 else "left the mode"


class LTLDSController(Controller):
    """LTL-DS (with modulation): the automaton picks the mode, its LPV-DS moves the agent.

    SoupScoop: one LPV-DS per mode in ``(x, y)``, fitted to experiment ``fit_seed``'s ``n_demos`` drawn
    demonstrations (3; thesis §3.7.2). ArmScoop: the same on the Panda arm's ``(y, z, pitch)`` state (the
    experiment's 2 expert demonstrations, ``n_demos`` ignored); the flow and the cuts are drawn in the
    ``(y, z)`` plane of the spoon (``x`` held at the bowls' axis) at the spoon's current pitch.
    """

    def __init__(self, env: Any, fit_seed: int = 0, n_demos: int = 3) -> None:
        from steer_envs.baselines.lpv_ds.task_policies import arm_scoop_policy, soup_scoop_policy

        base = env.unwrapped
        env_id = str(base.spec.id if base.spec else "")
        self.arm = hasattr(base, "perturb_workspace") and hasattr(base, "pitch")  # ArmScoop's spoon
        if self.arm:
            box = base.perturb_workspace
            self.low, self.high = np.asarray(box.low)[:2], np.asarray(box.high)[:2]
            self.plane_x = float(base.eef_pos[0])
        else:
            self.low, self.high = np.asarray(base.model.low), np.asarray(base.model.high)

        def build() -> Any:
            if self.arm:
                return arm_scoop_policy(fit_seed, modulation=True)
            return soup_scoop_policy(fit_seed, n_demos, env, modulation=True)

        self.policy = _cached(("ltl-ds", env_id, fit_seed, n_demos), build)
        self.modes: tuple[str, ...] = tuple(self.policy.modes)
        self.last_change = "–"
        self.replans = 0
        self._x = np.zeros(self.policy.dim)

    # -------------------------------------------------------- where the agent is
    def agent(self, base: Any) -> np.ndarray:
        """SoupScoop: the spoon's ``(x, y)``; ArmScoop: the spoon's tool point in the world."""
        if self.arm:
            return np.asarray(base.eef_pos, dtype=np.float64)
        return super().agent(base)

    def push_target(self, base: Any, point: np.ndarray) -> np.ndarray:
        """ArmScoop: the spoon's ``(y, z)`` of world ``point``, its pitch kept; SoupScoop: ``point``."""
        if self.arm:
            return np.array([point[1], point[2], float(base.state[2])])
        return point

    def _view_points(self, coords: np.ndarray) -> np.ndarray:
        """``(N, 2)`` flow-plane coordinates (SoupScoop ``(x, y)``, ArmScoop ``(y, z)``) -> points the view draws."""
        if self.arm:
            return np.concatenate([np.full((len(coords), 1), self.plane_x), coords], axis=1)
        return coords

    # -------------------------------------------------------------- acting
    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.policy.reset(obs, info)
        self.last_change, self.replans = "–", 0
        self._x = np.asarray(obs, dtype=np.float64).reshape(-1)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        seen = len(self.policy.events)
        action = np.asarray(self.policy.act(obs, info))
        self._x = np.asarray(obs, dtype=np.float64).reshape(-1)
        self._note(seen)
        return action

    def observe(self, obs: Any, info: dict[str, Any]) -> None:
        seen = len(self.policy.events)
        self.policy.observe(obs, info)
        self._x = np.asarray(obs, dtype=np.float64).reshape(-1)
        self._note(seen)

    def _note(self, seen: int) -> None:
        """Describe the mode changes since event ``seen``: a push or failure makes the automaton replan."""
        for event in self.policy.events[seen:]:
            change = f"{event.kind}: {event.source} → {event.target}"
            if event.kind != "planned":
                self.replans += 1
                order = {m: i for i, m in enumerate(self.modes)}
                gap = order.get(event.target, 0) - order.get(event.source, 0)
                change += f" ({_jump(gap)}; replanned: {' → '.join(self.policy.plan)})"
            if event.cut_added:
                change += ", cut learned"
            self.last_change = change

    # ------------------------------------------------------------- drawing
    def overlays(self, view: PushView, state: np.ndarray, full: bool) -> dict[str, Any]:
        mode = self.policy.mode
        xs = np.linspace(self.low[0], self.high[0], FLOW_GRID + 2)[1:-1]
        ys = np.linspace(self.low[1], self.high[1], FLOW_GRID + 2)[1:-1]
        plane = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        rest = np.tile(self._x[2:], (len(plane), 1))  # the slice through the agent's other coordinates (pitch)
        velocity = self.policy.flow(np.concatenate([plane, rest], axis=1), mode)[:, :2]
        speed = np.linalg.norm(velocity, axis=1, keepdims=True)
        top = float(speed.max() or 1.0) if self.arm else float(self.policy.max_speed or speed.max() or 1.0)
        cell = float(min(xs[1] - xs[0], ys[1] - ys[0])) * 0.8
        tips = plane + velocity / np.maximum(speed, 1e-12) * cell * np.minimum(speed / top, 1.0)
        start, end = view.to_pixels(self._view_points(plane)), view.to_pixels(self._view_points(tips))
        arrows = np.concatenate([start, end - start], axis=1)
        cuts = [self._cut_line(view, c.point, c.normal) for cs in self.policy.cut_sets.values() for c in cs.cuts]
        attractor = view.to_pixels(self._view_points(np.asarray(self.policy.dynamics[mode].attractor)[None, :2]))
        return {"flow": _round(arrows), "cuts": [c for c in cuts if c], "attractor": _round(attractor)}

    def _cut_line(self, view: PushView, point: np.ndarray, normal: np.ndarray) -> list[Any]:
        """A cut's boundary in the drawn plane (through the agent's other coordinates), clipped, in pixels."""
        n2 = np.asarray(normal[:2], dtype=np.float64)
        if float(np.linalg.norm(n2)) < 1e-9:
            return []  # the cut is parallel to the drawn plane
        offset = float(np.dot(normal[2:], self._x[2:] - point[2:])) if len(normal) > 2 else 0.0
        anchor = point[:2] - n2 * offset / float(n2 @ n2)  # n2 . (s - p2) = -offset on the line
        direction = np.array([-n2[1], n2[0]]) / float(np.linalg.norm(n2))
        span = float(np.linalg.norm(self.high - self.low))
        ts = np.linspace(-2 * span, 2 * span, 801)
        line = anchor[None, :] + ts[:, None] * direction[None, :]
        inside = np.all((line >= self.low) & (line <= self.high), axis=1)
        if inside.sum() < 2:
            return []
        kept = line[inside]
        return _round(view.to_pixels(self._view_points(kept[[0, -1]])))

    def panel(self, state: np.ndarray, info: dict[str, Any]) -> list[tuple[str, str]]:
        sensors = info.get("sensors", {})
        rows = [
            ("automaton mode", self.policy.mode),
            ("plan", " → ".join(self.policy.plan)),
            ("mode sensors", ", ".join(f"{k} {'on' if v else 'off'}" for k, v in sensors.items()) or "–"),
            ("last mode change", self.last_change),
            ("replans (pushes, failures)", str(self.replans)),
            ("learned cuts", str(self.policy.num_cuts)),
        ]
        if self.arm:
            y, z, pitch = self._x[:3]
            rows.append(("spoon (y, z, pitch)", f"{y:.3f} m, {z:.3f} m, {pitch:.2f} rad"))
        return rows


# ------------------------------------------------------------------ GLiDE
class GlideController(Controller):
    """GLiDE+Planning on PolygonNav over a mode classifier trained from success labels (cached under ``cache_dir``).

    ``setup``: :class:`~steer_envs.baselines.glide.polygon.GlideSetup` (default: the GLiDE suites' data and
    training, 2-3 minutes on one core the first time, then read from ``cache_dir``; :func:`quick_glide_setup`
    trains in about 15 s).
    """

    def __init__(self, env: Any, seed: int = 0, setup: Any = None, cache_dir: str | Path | None = None) -> None:
        from steer_envs.baselines.glide import make_polygon_policy

        base = env.unwrapped
        env_id = str(base.spec.id) if base.spec is not None else ""
        layout = int(base.model.layout_seed)
        cache = Path(cache_dir) if cache_dir is not None else DEFAULT_CACHE_DIR / "glide"
        key = ("glide-planning", env_id, layout, seed, repr(setup), str(cache))
        self.policy = _cached(
            key, lambda: make_polygon_policy("glide_planning", env_id, layout, seed, setup=setup, cache_dir=cache)[0]
        )
        self.mode_names: tuple[str, ...] = tuple(base.task.modes)
        self.size = int(base.render_size)
        self._map: str | None = None
        self._centres = _pixel_centres(base)

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.policy.reset()

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        return np.asarray(self.policy.act(np.asarray(obs, dtype=np.float64)[None, :2]))[0]

    def learned_mode(self, state: np.ndarray) -> int:
        """The classifier's mode at ``state``."""
        return int(self.policy.map.mode(np.asarray(state, dtype=np.float64)[None, :2])[0])

    def overlays(self, view: PushView, state: np.ndarray, full: bool) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if full:
            if self._map is None:
                modes = np.asarray(self.policy.map.mode(self._centres)).reshape(self.size, self.size)
                self._map = mode_map_png(modes)
            out["mode_map"] = {"src": self._map}
        ahead = self.policy.planned_path()  # the path being followed (replanned on a mode change or a push)
        path = np.concatenate([np.asarray(state[:2], dtype=np.float64)[None], ahead])
        out["plan"] = [_round(view.to_pixels(path))] if len(path) > 1 else []
        return out

    def panel(self, state: np.ndarray, info: dict[str, Any]) -> list[tuple[str, str]]:
        """The learned mode beside the true one."""
        learned = self.learned_mode(state)
        name = self.mode_names[learned] if 0 <= learned < len(self.mode_names) else str(learned)
        true = str(info.get("mode_name", "–"))
        planned = sum(getattr(self.policy, "stats", {}).values())
        return [
            ("learned mode", name),
            ("true mode", true),
            ("agree", "yes" if name == true else "no"),
            ("paths planned (mode changes, pushes)", str(planned)),
        ]


def quick_glide_setup() -> Any:
    """A smaller GLiDE data set and training for tests and demos: 300 + 300 replays, 500 epochs (about 15 s).

    (The suites': 1000 + 1000 replays, 2000 epochs.) On PolygonNav-3Mode layout 0 its learned modes
    overlap the true ones on 96 % of the grid, but GLiDE+Planning over them does not recover from
    every push (from the top-left corner it cuts into the second polygon; over the suites' it does not).
    """
    from dataclasses import replace

    from steer_envs.baselines.glide import GlideSetup

    base = GlideSetup()
    return replace(base, n_success=300, n_failure=300, train=replace(base.train, epochs=500, progress=False))


def _pixel_centres(base: Any) -> np.ndarray:
    """World points of a kinematic env's frame pixels, row-major (its Canvas's convention)."""
    from steer_envs.envs.render import Canvas

    size = int(base.render_size)
    return Canvas(base.model.low, base.model.high, size, size).pixel_centers()
