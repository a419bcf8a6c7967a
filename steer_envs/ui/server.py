"""steer-ui's web server: FastAPI serves the page, a WebSocket per tab drives one session.

Each connection gets its own session: a :class:`~steer_envs.ui.session.Session`
(env, sampler state, noise generator) for a domain that steers a policy, a
:class:`~steer_envs.ui.push_session.PushSession` (env, controller) for one
that pushes a controller; the policy's weights (or the fitted controller) are
loaded once and shared. The ``ready`` message carries the domain's
declaration (:mod:`steer_envs.ui.domains`), from which the page builds its
controls. Session calls run in a
thread pool, so a slow SS call never blocks the event loop or another tab;
messages are validated on the event loop first (:func:`parse_message`), so a
bad message is answered at once with an ``error`` and changes nothing.
Closing the tab closes its env.

Requests whose ``Host`` is not one of :attr:`UIConfig.allowed_hosts` are
refused, and so is a WebSocket whose ``Origin`` is not the page's own
(:mod:`steer_envs.ui.access`).
"""

from __future__ import annotations

import asyncio
import base64
import collections
import contextlib
import functools
import logging
import math
import time
from collections.abc import AsyncIterator, Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib import resources
from typing import Any, TypeVar

import numpy as np
from fastapi import FastAPI, WebSocket, WebSocketDisconnect
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.middleware.trustedhost import TrustedHostMiddleware

from steer_envs.core.validation import integer, one_of
from steer_envs.steering import SAMPLERS
from steer_envs.ui.access import LOCAL_HOSTS, same_origin
from steer_envs.ui.domains import DOMAINS
from steer_envs.ui.messages import Message, MessageError, parse_message
from steer_envs.ui.outcomes import SteerOutcome
from steer_envs.ui.push_session import PushSession, PushSettings
from steer_envs.ui.recording import Recording, recording_json
from steer_envs.ui.replay import replay
from steer_envs.ui.session import Session, shared_policy
from steer_envs.ui.settings import MAX_BATCH, SteerSettings
from steer_envs.ui.video import VIDEO_FORMATS, annotated_frame, encode_video
from steer_envs.ui.views import SessionError

__all__ = ["MAX_PENDING", "UIConfig", "create_app"]

log = logging.getLogger("steer_envs.ui")
T = TypeVar("T")

#: requests one connection may have waiting; beyond it the page is told to wait
MAX_PENDING = 32
#: seconds between play ticks (on top of the steering call itself)
PLAY_PAUSE_S = 0.02
#: the most frames an exported video holds (a frame per interaction or step)
MAX_VIDEO_FRAMES = 2000


@dataclass(frozen=True)
class UIConfig:
    """What the server serves: a domain (its env and policy unless overridden), and its limits."""

    domain: str = "maze2d"
    env: str | None = None
    policy: str | None = None
    checkpoint: str | None = None
    accelerate: str = "fastest"
    seed: int = 0
    #: session calls running at once (the rest wait in line; one torch thread each)
    workers: int = 2
    #: open connections at once; more are refused with a message
    max_sessions: int = 32
    #: the ``Host`` names requests may carry (this machine's by default; add the name a remote client uses)
    allowed_hosts: tuple[str, ...] = LOCAL_HOSTS
    #: where a push domain keeps what it trains (GLiDE's classifier; ``None``: ``~/.cache/steer-envs/ui``)
    cache_dir: str | None = None
    #: passed to a push domain's controller (:data:`~steer_envs.ui.drivers.CONTROLLERS`), e.g. GLiDE's ``setup``
    controller_options: Mapping[str, Any] | None = None


def _pixels(arr: np.ndarray) -> list[Any]:
    return np.round(np.asarray(arr, dtype=np.float64), 2).tolist()  # type: ignore[no-any-return]


def _finite_or_none(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in np.asarray(values, dtype=np.float64)]


class _Connection:
    """One tab: its session, a queue of requests and the play loop."""

    def __init__(self, websocket: WebSocket, app_state: _AppState) -> None:
        self.ws = websocket
        self.app = app_state
        self.session: Session | PushSession | None = None
        self.pending: collections.deque[Message] = collections.deque()
        self.wake = asyncio.Event()
        self.send_lock = asyncio.Lock()
        self.playing = False
        self.interaction: tuple[str, Any] = ("none", None)
        self.counter = 0

    async def call(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self.app.pool, functools.partial(fn, *args, **kwargs))

    async def send(self, payload: dict[str, Any]) -> None:
        async with self.send_lock:
            await self.ws.send_json(payload)

    async def error(self, message: str) -> None:
        await self.send({"type": "error", "message": message})

    # ---------------------------------------------------------------- serve
    async def serve(self) -> None:
        origin, host = self.ws.headers.get("origin"), self.ws.headers.get("host")
        if not same_origin(origin, host):
            log.warning("refused a WebSocket from origin %r (the page is served as %r)", origin, host)
            await self.ws.close(code=1008)  # before accept: the browser sees a refused handshake (HTTP 403)
            return
        await self.ws.accept()
        if len(self.app.active) >= self.app.config.max_sessions:
            await self.error(f"the server is full ({self.app.config.max_sessions} sessions); try again later")
            await self.ws.close(code=1013)
            return
        self.app.active.add(self)
        worker: asyncio.Task[None] | None = None
        try:
            self.session = await self.call(_open_session, self.app.config)
            worker = asyncio.create_task(self.work())
            await self.read()
        except WebSocketDisconnect:
            pass
        finally:
            self.app.active.discard(self)
            if worker is not None:
                worker.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await worker
            if self.session is not None:
                await self.call(self.session.close)

    async def read(self) -> None:
        while True:
            event = await self.ws.receive()
            if event["type"] == "websocket.disconnect":
                raise WebSocketDisconnect(int(event.get("code", 1000)))
            text = event.get("text")
            try:
                message = parse_message(text if text is not None else event.get("bytes"))
            except MessageError as exc:
                await self.error(str(exc))
                continue
            if message.type == "pause":  # at once, even while a call runs
                self.playing = False
                await self.send({"type": "playing", "playing": False})
                continue
            if len(self.pending) >= MAX_PENDING:
                await self.error(f"{MAX_PENDING} requests are already waiting; wait for the plans before sending more")
                continue
            self.pending.append(message)
            self.wake.set()

    async def work(self) -> None:
        while True:
            if not self.pending:
                if self.playing:
                    await self.guarded(self.tick)
                    await asyncio.sleep(PLAY_PAUSE_S)
                    continue
                self.wake.clear()
                await self.wake.wait()
                continue
            message = self.pending.popleft()
            if message.type == "steer" and any(m.type == "steer" for m in self.pending):
                continue  # a newer sketch is waiting: skip the stale one
            await self.guarded(self.handle, message)

    async def guarded(self, fn: Callable[..., Any], *args: Any) -> None:
        try:
            await fn(*args)
        except (SessionError, MessageError, ValueError, TypeError) as exc:
            await self.stop_playing()
            await self.error(str(exc))
        except WebSocketDisconnect:
            raise
        except Exception as exc:  # a bug must not take the server down: log it and tell the page
            log.exception("steer-ui request failed")
            await self.stop_playing()
            await self.error(f"internal error ({type(exc).__name__}: {exc})")

    async def stop_playing(self) -> None:
        """Stop the play loop and tell the page (its button turns back to Play)."""
        if self.playing:
            self.playing = False
            await self.send({"type": "playing", "playing": False})

    # -------------------------------------------------------------- requests
    async def handle(self, message: Message) -> None:
        session = self.session
        assert session is not None
        fields = message.fields
        if message.type == "hello":
            await self.send(await self.call(self.ready_payload))
        elif message.type == "configure":
            configure: Callable[..., SteerSettings | PushSettings] = session.configure
            settings = await self.call(configure, **fields)
            await self.send({"type": "settings", "settings": settings.as_dict()})
        elif message.type == "reset":
            await self.stop_playing()
            seed = fields.get("seed")
            await self.call(session.reset, None if seed is None else integer(seed, "`seed`", low=0, high=2**31 - 1))
            await self.send(await self.call(self.frame_payload, None, "reset"))
        elif message.type == "steer":
            if not isinstance(session, Session):
                raise SessionError(f"{self.app.config.domain} is steered by pushing the agent (Push mode), not plans")
            started = time.perf_counter()
            kind, points = fields["kind"], fields.get("points")
            outcome = await self.call(session.steer_pixels, kind, points)
            self.interaction = (kind, points)
            await self.send(self.plans_payload(outcome, started))
        elif message.type == "step":
            await self.send(await self.call(self.step_payload))
        elif message.type == "play":
            self.playing = True
            await self.send({"type": "playing", "playing": True})
        elif message.type in ("nudge", "push"):
            started = time.perf_counter()
            to = fields["to"]
            if not isinstance(to, list) or len(to) != 2:
                raise MessageError(f"'to' must be a [u, v] pixel pair, got {str(to)[:80]}")
            if message.type == "nudge" and isinstance(session, Session):
                info = await self.call(session.nudge_pixel, to[0], to[1])
            elif message.type == "push" and isinstance(session, PushSession):
                info = await self.call(session.push_pixel, to[0], to[1])
            else:
                offered = ", ".join(session.kinds) or "none"
                raise SessionError(f"{self.app.config.domain} takes no {message.type} (its interactions: {offered})")
            pushed = (time.perf_counter() - started) * 1e3
            payload = await self.call(self.frame_payload, info, message.type)
            payload["timings"] = {"push_ms": pushed, "server_ms": (time.perf_counter() - started) * 1e3}
            await self.send(payload)
        elif message.type == "save":
            recording = session.recording()
            text = recording_json(recording)
            name = f"steer-ui-{self.app.config.domain}-seed{recording.seed}-{len(recording.events)}events.json"
            await self.send(_download(name, "application/json", text.encode("utf-8")))
        elif message.type == "export":
            fmt = one_of(fields.get("format") or "mp4", "format", VIDEO_FORMATS, owner="export")
            recording = session.recording()
            data, identical = await self.call(_export, recording, fmt, self.app.config)
            name = f"steer-ui-{self.app.config.domain}-seed{recording.seed}.{fmt}"
            await self.send(
                {**_download(name, f"video/{fmt}" if fmt == "mp4" else "image/gif", data), "identical": identical}
            )

    async def tick(self) -> None:
        session = self.session
        assert session is not None
        if isinstance(session, PushSession):  # the controller runs on; no plans to sample
            payload = await self.call(self.step_payload)
            await self.send(payload)
            if payload["done"]:
                await self.stop_playing()
            return
        started = time.perf_counter()
        kind, points = self.interaction
        outcome = await self.call(session.steer_pixels, kind, points)
        await self.send(self.plans_payload(outcome, started))
        payload = await self.call(self.step_payload)
        await self.send(payload)
        if payload["done"]:
            await self.stop_playing()

    # -------------------------------------------------------------- payloads
    def ready_payload(self) -> dict[str, Any]:
        session = self.session
        assert session is not None
        name = self.app.config.domain
        payload = {
            **self.frame_payload(None, "ready"),
            "type": "ready",
            "domain": name,
            "declaration": session.domain.declaration(name, session.kinds),
            "env": str(getattr(session.env.spec, "id", "")),
            "kinds": list(session.kinds),
            "max_batch": MAX_BATCH,
            "width": session.pixels.width,
            "height": session.pixels.height,
            "settings": session.settings.as_dict(),
        }
        if isinstance(session, PushSession):
            return {**payload, "policy": session.domain.controller, "samplers": [], "diffusion": False, "horizon": 0}
        policy = session.policy
        collide = callable(getattr(session.env.unwrapped, "plan_collides", None)) and len(session.dims) == 2
        return {
            **payload,
            "collisions": collide,
            "policy": self.app.config.policy or session.domain.policies[0],
            "samplers": list(SAMPLERS),
            "diffusion": bool(hasattr(policy, "predict_noise")),
            "horizon": int(policy.horizon) - int(getattr(policy, "exec_start", 0)),
        }

    def frame_payload(self, info: dict[str, Any] | None, why: str, executed: Any = None) -> dict[str, Any]:
        session = self.session
        assert session is not None
        encode = time.perf_counter()
        png = base64.b64encode(session.frame_png()).decode("ascii")
        info = info or {}
        extra: dict[str, Any] = {"panel": [list(row) for row in session.panel()]}
        if isinstance(session, PushSession):
            extra["overlays"] = session.overlays(full=why in ("ready", "reset"))
            extra["notice"] = session.notice
        return {
            **extra,
            "type": "frame",
            "why": why,
            "image": "data:image/png;base64," + png,
            "agent": _pixels(session.pixels.to_pixels(session.state)),
            "steps": session.steps if isinstance(session, PushSession) else None,
            "executed": [] if executed is None or len(executed) == 0 else _pixels(session.pixels.to_pixels(executed)),
            "seed": session.seed,
            "success": bool(info.get("success", False)),
            "violation": bool(info.get("constraint_violation", False)),
            "mode": str(info.get("mode_name", "")),
            "done": session.done,
            "encode_ms": (time.perf_counter() - encode) * 1e3,
        }

    def step_payload(self) -> dict[str, Any]:
        session = self.session
        assert session is not None
        step = session.execute()
        payload = self.frame_payload(step.info, "step", step.executed if len(step.executed) else None)
        payload["reward"] = step.reward
        return payload

    def plans_payload(self, outcome: SteerOutcome, started: float) -> dict[str, Any]:
        session = self.session
        assert isinstance(session, Session)
        self.counter += 1
        interaction = outcome.interaction
        drawn: list[Any] = []
        if interaction is not None:
            data = getattr(interaction, "points", None)
            if data is None:
                data = np.asarray(interaction.target)[None]  # type: ignore[union-attr]
            drawn = _pixels(session.pixels.to_pixels(data))
        costs = outcome.costs
        payload: dict[str, Any] = {
            "type": "plans",
            "id": self.counter,
            "sampler": outcome.settings.sampler if interaction is not None else "RS",
            "kind": "none" if interaction is None else interaction.kind,
            "plans": _pixels(session.pixels.to_pixels(outcome.plans)),
            "chosen": outcome.chosen,
            "collides": None if outcome.collides is None else [bool(c) for c in outcome.collides],
            "costs": _finite_or_none(costs),
            "interaction": drawn,
            "timings": {**outcome.timings, "server_ms": (time.perf_counter() - started) * 1e3},
        }
        rows = session.panel(outcome)
        if rows:
            payload["panel"] = [list(row) for row in rows]
        return payload


def _download(name: str, mime: str, data: bytes) -> dict[str, Any]:
    """A ``download`` message: the page saves ``data`` as file ``name``."""
    return {"type": "download", "name": name, "mime": mime, "size": len(data), "data": base64.b64encode(data).decode()}


def _export(recording: Recording, fmt: str, config: UIConfig) -> tuple[bytes, bool]:
    """Replay ``recording`` in a fresh session and encode its rollout (plans drawn); whether the frames matched."""
    frames: list[np.ndarray] = []

    def grab(index: int, event: Any, session: Any, outcome: Any) -> None:
        if len(frames) < MAX_VIDEO_FRAMES:
            frames.append(annotated_frame(session, outcome))

    replayed = replay(recording, controller_options=_controller_options(config), on_event=grab)
    try:
        if not frames:
            frames.append(annotated_frame(replayed.session))
        return encode_video(frames, fmt), replayed.identical
    finally:
        replayed.session.close()


@dataclass
class _AppState:
    config: UIConfig
    pool: ThreadPoolExecutor
    active: set[_Connection]
    #: how long the start-up steering call took (the network's compilation happens there, not at a user's first call)
    warm_up_ms: float = 0.0


def _controller_options(config: UIConfig) -> dict[str, Any]:
    """A push domain's controller options: the config's, with ``cache_dir`` for the GLiDE controllers."""
    options = dict(config.controller_options or {})
    if DOMAINS[config.domain].controller in ("glide-planning", "glide-bc-arm") and config.cache_dir:
        options.setdefault("cache_dir", config.cache_dir)
    return options


def _open_session(config: UIConfig) -> Session | PushSession:
    """A session of the served domain, env and policy (the weights are shared across sessions)."""
    domain = DOMAINS[config.domain]
    if not domain.steering:
        if config.env is not None or config.policy is not None or config.checkpoint is not None:
            raise ValueError(f"steer-ui: the {config.domain!r} domain takes no --env, --policy or --checkpoint")
        return PushSession(config.domain, seed=config.seed, controller_options=_controller_options(config))
    return Session(
        config.domain,
        env=config.env,
        policy=config.policy,
        checkpoint=config.checkpoint,
        accelerate=config.accelerate,
        seed=config.seed,
        threads=None,  # set once per process (steer-ui --threads); not per call from many threads
    )


def _warm_up(config: UIConfig) -> float:
    """One unsteered call of a throw-away session: per-shape compilation and caches happen before serving."""
    started = time.perf_counter()
    session = _open_session(config)
    try:
        if isinstance(session, PushSession):
            session.execute()
            session.overlays(full=True)
        else:
            session.steer(None)
    finally:
        session.close()
    return (time.perf_counter() - started) * 1e3


def create_app(config: UIConfig | None = None) -> FastAPI:
    """The steer-ui FastAPI app (serve it with uvicorn); loads the policy once, before the first connection."""
    config = config or UIConfig()
    one_of(config.domain, "domain", tuple(DOMAINS), owner="steer-ui")
    integer(config.workers, "`workers`", low=1, high=64)
    integer(config.max_sessions, "`max_sessions`", low=1, high=1024)
    state = _AppState(config, ThreadPoolExecutor(config.workers, thread_name_prefix="steer-ui"), set())

    @contextlib.asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        loop = asyncio.get_running_loop()
        domain = DOMAINS[config.domain]
        if domain.steering:
            policy = config.policy or domain.policies[0]
            await loop.run_in_executor(state.pool, shared_policy, policy, config.checkpoint, config.accelerate)
        state.warm_up_ms = await loop.run_in_executor(state.pool, _warm_up, config)
        try:
            yield
        finally:
            state.pool.shutdown(wait=False, cancel_futures=True)

    app = FastAPI(title="steer-ui", lifespan=lifespan, docs_url=None, redoc_url=None)
    hosts = [h.strip("[]") for h in config.allowed_hosts]
    app.add_middleware(TrustedHostMiddleware, allowed_hosts=[*hosts, *(f"[{h}]" for h in hosts if ":" in h)])
    static = resources.files("steer_envs.ui") / "static"
    app.mount("/static", StaticFiles(directory=str(static)), name="static")
    index = (static / "index.html").read_text(encoding="utf-8")

    @app.get("/", response_class=HTMLResponse)
    async def page() -> HTMLResponse:
        return HTMLResponse(index)

    @app.get("/api/health")
    async def health() -> JSONResponse:
        return JSONResponse(
            {"status": "ok", "sessions": len(state.active), "domain": config.domain, "warm_up_ms": state.warm_up_ms}
        )

    @app.websocket("/ws")
    async def steer_socket(websocket: WebSocket) -> None:
        await _Connection(websocket, state).serve()

    app.state.steer_ui = state
    return app
