"""Push and watch: a closed-loop controller runs the env, a person drags the agent, the controller recovers.

A :class:`PushSession` is what steer-ui keeps per tab for a ``"push"`` domain
(TLI's SoupScoop and ArmScoop under LTL-DS, GLiDE+Planning on PolygonNav,
GLiDE+BC on the Lift arm), the counterpart
of :class:`~steer_envs.ui.session.Session` for policies that are steered::

    session = PushSession("soup-scoop", seed=1)
    session.execute()                        # the controller runs 10 steps
    session.push_pixel(40, 200)              # drag the spoon there (env.unwrapped.perturb(to=...))
    session.execute()                        # the automaton replans; the flow recovers
    session.panel()                          # mode, plan, sensors, the last mode change

A push the env refuses (a pose the arm cannot take: ``perturb`` raises a
``ValueError`` naming ``to``) moves nothing and is kept as :attr:`PushSession.notice`,
for the page to show; the session goes on. A session is not thread-safe: one
call at a time.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from steer_envs.core.env import PerturbableEnv
from steer_envs.core.validation import integer, real_array
from steer_envs.ui.controllers import Controller, PushView
from steer_envs.ui.domains import DOMAINS, domain_named
from steer_envs.ui.drivers import make_controller
from steer_envs.ui.outcomes import StepOutcome
from steer_envs.ui.recording import Recording, SessionLog, json_options, recording_of
from steer_envs.ui.views import PixelMap, PlaneView, SessionError, make_view, rendered_frame

__all__ = ["MAX_STEPS", "PushSession", "PushSettings"]

#: the most env steps one Step may run
MAX_STEPS = 1000


@dataclass(frozen=True)
class PushSettings:
    """A push session's one knob: env steps per :meth:`PushSession.execute` (a Step, a play tick)."""

    execute: int = 10

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"execute": self.execute}


class PushSession:
    """An env driven by a domain's controller; :meth:`push` drags the agent, :meth:`execute` runs steps.

    Args:
        domain: a ``"push"`` domain of :data:`~steer_envs.ui.domains.DOMAINS` (``"soup-scoop"``,
            ``"arm-scoop"``, ``"polygon-nav"``, ``"lift-glide"``).
        seed: the first reset's seed.
        env_kwargs: passed to ``gymnasium.make`` (default: the domain's).
        controller_options: passed to the controller (e.g. ``cache_dir`` for GLiDE's classifier).
    """

    def __init__(
        self,
        domain: str = "soup-scoop",
        *,
        seed: int = 0,
        env_kwargs: dict[str, Any] | None = None,
        controller_options: dict[str, Any] | None = None,
    ) -> None:
        self.name = domain
        self.domain = domain_named(domain, owner="PushSession")
        #: the calls that changed the session, for :meth:`recording` (:class:`~steer_envs.ui.recording.SessionLog`)
        self.log = SessionLog()
        self._logging = False
        recorded, unrecorded = json_options(controller_options)
        self._opened: dict[str, Any] = {
            "kind": "push",
            "seed": seed,
            "env_kwargs": None if env_kwargs is None else dict(env_kwargs),
            "controller_options": recorded,
            "unrecorded_options": unrecorded,
        }
        if self.domain.steering:
            raise SessionError(f"the {domain!r} domain steers a policy: open it with Session, not PushSession")
        kwargs = dict(self.domain.env_kwargs if env_kwargs is None else env_kwargs)
        self.env = gym.make(self.domain.env_id, render_mode="rgb_array", **kwargs)
        base = self.env.unwrapped
        if not isinstance(base, PerturbableEnv):
            self.env.close()
            raise SessionError(f"{type(base).__name__} cannot be pushed (it has no perturb())")
        self.settings = PushSettings(self.domain.steps)
        self.controller: Controller = make_controller(self.domain.controller, self.env, **(controller_options or {}))
        self.kinds: tuple[str, ...] = tuple(self.domain.interactions)
        self._obs: Any = None
        self._info: dict[str, Any] = {}
        self._done = False
        self._steps = 0
        self._seed = integer(seed, "`seed`", low=0, high=2**31 - 1)
        self.notice = ""
        self.reset(seed=self._seed)
        self.pixels: PushView = self._view()
        self._logging = True

    def _view(self) -> PushView:
        view = make_view(self.domain.view, self.env.unwrapped, self.frame())
        if not isinstance(view, PixelMap | PlaneView):
            raise SessionError("a push session draws a top-down box or a camera's drag plane")
        return view

    # -------------------------------------------------------------- state
    @property
    def seed(self) -> int:
        """The seed of the last reset."""
        return self._seed

    @property
    def state(self) -> np.ndarray:
        """The agent's position as the view draws it (a kinematic env's ``(x, y)``; an arm's tool point, m)."""
        return self.controller.agent(self.env.unwrapped)

    @property
    def done(self) -> bool:
        """The episode ended (success, a terminating violation or the step limit): :meth:`reset` to go on."""
        return self._done

    @property
    def info(self) -> dict[str, Any]:
        """The env's latest info (after the last reset, step or push)."""
        return dict(self._info)

    @property
    def steps(self) -> int:
        """Env steps since the last reset."""
        return self._steps

    def configure(self, **knobs: Any) -> PushSettings:
        """Change ``execute`` (env steps per Step; ``None``: the domain's). Other knobs give ``TypeError``."""
        unknown = sorted(set(knobs) - {"execute"})
        if unknown:
            raise TypeError(f"PushSession.configure: a push session has one knob, 'execute'; got {unknown}")
        if "execute" in knobs:
            value = knobs["execute"]
            steps = self.domain.steps if value is None else integer(value, "`execute`", low=1, high=MAX_STEPS)
            self.settings = PushSettings(steps)
        self._record("configure", knobs=self.settings.as_dict())
        return self.settings

    def reset(self, seed: int | None = None) -> dict[str, Any]:
        """A new episode (``seed``: its start state); the controller starts afresh (learned cuts are kept)."""
        if seed is not None:
            self._seed = integer(seed, "`seed`", low=0, high=2**31 - 1)
        self._obs, info = self.env.reset(seed=self._seed)
        self._info = dict(info)
        self.controller.reset(self._obs, self._info)
        self._done = False
        self._steps = 0
        self.notice = ""
        self._record("reset", seed=self._seed)
        return dict(info)

    # ------------------------------------------------------------- acting
    def execute(self) -> StepOutcome:
        """Run the controller for ``settings.execute`` env steps (fewer when the episode ends)."""
        if self._done:
            raise SessionError("the episode has ended: reset to go on")
        self.notice = ""
        trail = [self.state]
        reward, terminated, truncated = 0.0, False, False
        for _ in range(self.settings.execute):
            action = self.controller.act(self._obs, self._info)
            self._obs, r, terminated, truncated, info = self.env.step(action)
            self._info = dict(info)
            self._steps += 1
            reward += float(r)
            trail.append(self.state)
            if terminated or truncated:
                break
        self._done = bool(terminated or truncated)
        if self._done:
            self.controller.observe(self._obs, self._info)  # the final reading (e.g. the goal mode)
        self._record("step")
        return StepOutcome(np.asarray(trail), reward, bool(terminated), bool(truncated), dict(self._info))

    def push(self, to: Any) -> dict[str, Any]:
        """Drag the agent to point ``to`` of the view's space (``env.unwrapped.perturb(to=...)``).

        The controller sees the push at once. A push the env refuses (``ValueError`` from ``perturb``) moves
        nothing: its message becomes :attr:`notice` and the env's latest info is returned unchanged.
        """
        dim = len(self.state)
        target = real_array(to, "to", owner="PushSession.push")
        if target.shape != (dim,):
            raise SessionError(f"`to` must be a point of {dim} numbers, got shape {target.shape}")
        if self._done:
            raise SessionError("the episode has ended: reset to go on")
        base: Any = self.env.unwrapped
        self._record("push", to=target)
        try:
            info = dict(base.perturb(to=self.controller.push_target(base, target)))
        except ValueError as exc:  # refused before anything moved (e.g. a pose the arm cannot take)
            self.notice = f"push refused: {exc}"
            return dict(self._info)
        self.notice = ""
        self._obs = np.asarray(base._obs()) if callable(getattr(base, "_obs", None)) else self._obs
        self._info = info
        self.controller.observe(self._obs, info)
        return info

    def push_pixel(self, u: Any, v: Any) -> dict[str, Any]:
        """:meth:`push` to the point under pixel ``(u, v)`` (a camera view: on the drag plane through the agent)."""
        pixel = self.pixels.check_pixels([[u, v]], "to")
        if isinstance(self.pixels, PlaneView):
            return self.push(self.pixels.to_world(pixel, float(self.state[self.pixels.axis]))[0])
        return self.push(self.pixels.to_world(pixel)[0])

    # ------------------------------------------------------------ drawing
    def overlays(self, full: bool = False) -> dict[str, Any]:
        """The controller's overlays in pixels (``full``: also the static ones, e.g. the learned mode map)."""
        return self.controller.overlays(self.pixels, self.state, full)

    def panel(self) -> list[tuple[str, str]]:
        """Rows the page shows beside the view (the controller's, then the step count)."""
        return [*self.controller.panel(self.state, self._info), ("steps", str(self._steps))]

    def frame(self) -> np.ndarray:
        """The env's rendered view ``(H, W, 3)`` uint8."""
        image = rendered_frame(self.env)
        self.log.frame(image)
        return image

    # ------------------------------------------------------------ recording
    def _record(self, op: str, **fields: Any) -> None:
        if self._logging:
            self.log.add(op, **fields)

    def recording(self) -> Recording:
        """This session as a :class:`~steer_envs.ui.recording.Recording` (save it with ``save_recording``).

        Controller options that are not plain JSON (e.g. a GLiDE ``setup``) are named in the recording's
        ``unrecorded_options``; a replay must be given them.
        """
        return recording_of(self, self._opened, self.log)

    def frame_png(self) -> bytes:
        """:meth:`frame` as PNG bytes."""
        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(self.frame()).save(buffer, format="PNG", compress_level=1)
        return buffer.getvalue()

    def close(self) -> None:
        """Close the env."""
        self.env.close()


#: the push domains (for ``--domain`` help and tests)
PUSH_DOMAINS: tuple[str, ...] = tuple(name for name, d in DOMAINS.items() if not d.steering)
