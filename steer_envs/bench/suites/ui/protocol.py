"""The two steer-ui trials: a round trip's latency split, and a bounded load test.

``roundtrip``: serve steer-ui's ``domain`` in-process and time its gesture
``roundtrips`` times. A steered domain (ITPS): one sketch (Maze2D) or click
(BlockStack: a cube; Kitchen: the door handle), then re-steered, timing input
sent -> plans drawn; the server reports the policy network's time and the
sampler's own. A push domain (TLI, GLiDE): the agent dragged to a domain's
point and back (SoupScoop and ArmScoop: into the soup; PolygonNav: the far
corner; Lift: up), timing push sent -> frame drawn; the server reports the
push's own time (``perturb`` and the controller's reading) instead of network
and sampler. In a headless chromium when one is installed (``browser="auto"``),
the page's own clock gives the drawing time; otherwise a WebSocket client
stands in for the page (drawing 0). The trial's extras name the CPU.

``load``: ``connections`` clients steer as fast as the server answers for
``duration_s`` seconds while one more sends ``malformed`` bad messages; a
connection that closes or a reply that is an error where plans were due counts
as dropped / an error; the process's resident memory is sampled after a
warm-up and at the end (the server runs in this process).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Trial

#: bad messages the malformed-message client cycles through
MALFORMED: tuple[str, ...] = (
    "{bad json",
    '{"type": "launch"}',
    '{"type": "steer", "kind": "sketch", "points": [[NaN, 1], [2, 2]]}',
    '{"type": "steer", "kind": "sketch", "points": [[1e9, 1], [2, 2]]}',
    '{"type": "steer", "kind": "blob"}',
    '{"type": "configure", "batch": 100000000}',
    '{"type": "nudge", "to": [1]}',
    "[" * 5000,
    '{"type": "steer", "kind": "sketch", "points": "' + "x" * 300_000 + '"}',
    '{"type": "reset", "seed": -1}',
)
REPLY_TIMEOUT_S = 300.0
#: seconds a domain may take to set up before its server listens (lift-glide trains its classifier on first use)
SETUP_TIMEOUT_S = 1800.0


def _rss_mb() -> float:
    """Resident memory of this process in MiB (Linux ``/proc``; NaN elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return float("nan")
    import os

    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _sketch(agent: np.ndarray, rng: np.random.Generator | None = None) -> list[list[float]]:
    """A sketch from the agent: up two cells, then sideways (pixels, 32 a cell), jittered with ``rng``."""
    path = agent + np.array([[0.0, 0.0], [0.0, -32.0], [0.0, -64.0], [32.0, -64.0]])
    if rng is not None:
        path = path + rng.normal(0.0, 4.0, path.shape)
    return np.clip(path, 1.0, [383.0, 287.0]).tolist()  # type: ignore[no-any-return]


class _Client:
    """A WebSocket client speaking the page's protocol."""

    def __init__(self, url: str) -> None:
        from websockets.sync.client import connect

        self._connection = connect(url, max_size=2**24, open_timeout=60)
        self.ws = self._connection.__enter__()

    def ask(self, message: Any, until: tuple[str, ...] = ()) -> dict[str, Any]:
        self.ws.send(message if isinstance(message, str) else json.dumps(message))
        while True:
            reply: dict[str, Any] = json.loads(self.ws.recv(timeout=REPLY_TIMEOUT_S))
            if not until or reply["type"] in (*until, "error"):
                return reply

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


def steering(params: Any) -> tuple[str, int]:
    """The sampler and batch a trial steers with: ``params``', or the domain's own where they are unset."""
    from steer_envs.ui.domains import DOMAINS

    own = DOMAINS[params.domain].settings
    return params.sampler or own.sampler, params.batch or own.batch


def _settings(params: Any) -> dict[str, Any]:
    sampler, batch = steering(params)
    return {"type": "configure", "sampler": sampler, "batch": batch, "mcmc_steps": params.mcmc_steps}


def gesture(domain: str, seed: int, agent: np.ndarray) -> tuple[str, list[list[float]]]:
    """The scripted input of ``domain`` from the page's ``agent`` pixel: ``("sketch" | "point", pixels)`` for a
    steered domain, ``("push", [target, back])`` (pixels the agent is dragged to, in turn) for a push domain."""
    import gymnasium as gym

    from steer_envs.ui.domains import DOMAINS
    from steer_envs.ui.views import PixelMap, PlaneView

    start = [float(v) for v in agent]
    spec = DOMAINS[domain]
    if domain == "maze2d":
        return "sketch", _sketch(agent)
    if domain == "lift-glide":
        return "push", [[start[0], start[1] - 25.0], start]
    env = gym.make(spec.env_id, render_mode="rgb_array", **spec.env_kwargs)
    try:
        env.reset(seed=seed)
        base: Any = env.unwrapped
        if domain == "blockstack":
            return "point", [base.world_to_pixel(base.cube_pos[0])[:2].tolist()]
        if domain == "kitchen":
            return "point", [base.world_to_pixel(base.handle_pos)[:2].tolist()]
        if domain == "arm-scoop":
            from steer_envs.envs.robosuite.arm_scoop import BOWL_X, SOUP_SURFACE, SOUP_Y

            soup = PlaneView(base).to_pixels([BOWL_X, SOUP_Y, SOUP_SURFACE - 0.03])
            return "push", [soup.tolist(), start]
        frame = np.asarray(env.render())
        view = PixelMap.from_box(base.model.low, base.model.high, frame.shape[1], frame.shape[0])
        world = {"soup-scoop": (-2.0, -6.0), "polygon-nav": (7.0, -7.0)}[domain]
        return "push", [view.to_pixels(np.asarray(world)).tolist(), start]
    finally:
        env.close()


def _roundtrip_browser(server: Any, params: Any, seed: int, out: Path | None) -> list[dict[str, float]]:
    from steer_envs.ui.browser import open_page

    page = open_page(server.url)
    try:
        page.wait_ready(600)
        steered = bool(page.state("declaration")["steering"])
        kind, pixels = gesture(params.domain, seed, np.asarray(page.state("agent")))
        if not steered:
            for i in range(params.roundtrips):
                frames = int(page.state("frames"))
                page.drag([page.state("agent"), pixels[i % len(pixels)]])
                page.wait(f"window.steerUI.frames > {frames}", REPLY_TIMEOUT_S, "the pushed frame")
            return [h for h in page.state("history") if h.get("kind") == "push"][-params.roundtrips :]
        sampler, batch = steering(params)
        page.choose("sampler", sampler)
        page.wait(f"window.steerUI.settings.sampler === {sampler!r}", 60, "sampler chosen")
        for key, value in (("batch", batch), ("mcmc_steps", params.mcmc_steps)):
            page.driver.execute_script(
                "const el = document.getElementById(arguments[0]); el.value = arguments[1];"
                "el.dispatchEvent(new Event('change'));",
                key,
                "" if value is None else str(value),
            )
        page.wait(f"window.steerUI.settings.batch === {batch}", 60, "batch set")
        page.set_mode(kind)
        page.drag(pixels)
        page.wait("window.steerUI.plansReceived >= 1", REPLY_TIMEOUT_S, "first plans")
        received = int(page.state("plansReceived"))
        for _ in range(params.roundtrips):
            page.click_button("resteer")
            received += 1
            page.wait(f"window.steerUI.plansReceived >= {received}", REPLY_TIMEOUT_S, "plans")
        if out is not None:
            page.screenshot(out / ("steer-ui.png" if params.domain == "maze2d" else f"ui-{params.domain}.png"))
        history = page.state("history")
        return [h for h in history[-params.roundtrips - 1 :]]  # the first steering call after ready, then the rest
    finally:
        page.close()


def _roundtrip_socket(server: Any, params: Any, seed: int) -> list[dict[str, float]]:
    client = _Client(server.ws_url)
    try:
        ready = client.ask({"type": "hello"}, ("ready",))
        kind, pixels = gesture(params.domain, seed, np.asarray(ready["agent"]))
        rows = []
        if kind == "push":
            for i in range(params.roundtrips):
                t0 = time.perf_counter()
                reply = client.ask({"type": "push", "to": pixels[i % len(pixels)]}, ("frame",))
                if reply["type"] == "error":
                    raise RuntimeError(f"steer-ui answered a push with an error: {reply['message']}")
                rows.append({**reply["timings"], "roundtrip_ms": (time.perf_counter() - t0) * 1e3, "draw_ms": 0.0})
            return rows
        client.ask(_settings(params), ("settings",))
        message = {"type": "steer", "kind": kind, "points": pixels}
        t0 = time.perf_counter()
        first = client.ask(message, ("plans",))  # the first steering call after ready
        rows.append({**first["timings"], "roundtrip_ms": (time.perf_counter() - t0) * 1e3, "draw_ms": 0.0})
        for _ in range(params.roundtrips):
            t0 = time.perf_counter()
            reply = client.ask(message, ("plans",))
            if reply["type"] == "error":
                raise RuntimeError(f"steer-ui answered a steer with an error: {reply['message']}")
            rows.append({**reply["timings"], "roundtrip_ms": (time.perf_counter() - t0) * 1e3, "draw_ms": 0.0})
        return rows
    finally:
        client.close()


def _median(rows: list[dict[str, float]], key: str) -> float | None:
    values = [r[key] for r in rows if r.get(key) is not None]
    return float(np.median(values)) if values else None


def run_roundtrip(params: Any, seed: int, out: Path | None) -> dict[str, float | None]:
    """Median latency split of ``params.roundtrips`` round trips of ``params.domain``'s gesture."""
    from steer_envs.ui.browser import BrowserUnavailable, RunningServer, chromium_paths
    from steer_envs.ui.server import UIConfig

    use_browser = params.browser == "yes"
    if params.browser == "auto":
        try:
            chromium_paths()
            use_browser = True
        except BrowserUnavailable:
            use_browser = False
    config = UIConfig(
        domain=params.domain,
        seed=seed,
        workers=1,
        accelerate=params.accelerate,
        cache_dir=params.cache_dir or None,
    )
    with RunningServer(config, start_timeout=SETUP_TIMEOUT_S) as server:
        rows = _roundtrip_browser(server, params, seed, out) if use_browser else _roundtrip_socket(server, params, seed)
    from steer_envs.ui.domains import DOMAINS

    first_ratio = None
    if DOMAINS[params.domain].steering:
        first, rows = rows[0], rows[1:]
        first_ratio = float(first["roundtrip_ms"]) / float(np.median([r["roundtrip_ms"] for r in rows]))
    keys = ("network_ms", "sampler_ms", "push_ms", "server_ms", "draw_ms")
    med = {k: _median(rows, k) for k in keys}
    roundtrip = float(np.median([r["roundtrip_ms"] for r in rows]))
    return {
        **med,
        "roundtrip_ms": roundtrip,
        "transfer_ms": max(0.0, roundtrip - (med["server_ms"] or 0.0) - (med["draw_ms"] or 0.0)),
        "under_target": 100.0 * float(roundtrip < params.target_ms),
        "first_ratio": first_ratio,
        "browser": 1.0 if use_browser else 0.0,
    }


class _LoadClients:
    """The load test's clients (one thread each) and what they count, under one lock."""

    def __init__(self, params: Any, seed: int) -> None:
        self.params, self.seed = params, seed
        self.counts = {"calls": 0, "dropped": 0, "errors": 0, "malformed_answered": 0}
        self.latencies: list[float] = []
        self.lock = threading.Lock()
        self.stop_at = 0.0

    def steer_loop(self, index: int, url: str) -> None:
        """Steer with random sketches until :attr:`stop_at`, timing each call."""
        rng = np.random.default_rng([self.seed, index])
        try:
            client = _Client(url)
            ready = client.ask({"type": "hello"}, ("ready",))
            client.ask(_settings(self.params), ("settings",))
            while time.monotonic() < self.stop_at:
                message = {"type": "steer", "kind": "sketch", "points": _sketch(np.asarray(ready["agent"]), rng)}
                t0 = time.perf_counter()
                reply = client.ask(message, ("plans",))
                with self.lock:
                    if reply["type"] == "error":
                        self.counts["errors"] += 1
                    else:
                        self.counts["calls"] += 1
                        self.latencies.append((time.perf_counter() - t0) * 1e3)
            client.close()
        except Exception:  # a closed connection or a timeout: the client was dropped
            with self.lock:
                self.counts["dropped"] += 1

    def malformed_loop(self, url: str) -> None:
        """Send ``params.malformed`` malformed messages, counting those answered with an error."""
        try:
            client = _Client(url)
            client.ask({"type": "hello"}, ("ready",))
            for i in range(self.params.malformed):
                reply = client.ask(MALFORMED[i % len(MALFORMED)])
                if reply["type"] == "error":
                    with self.lock:
                        self.counts["malformed_answered"] += 1
            client.close()
        except Exception:
            with self.lock:
                self.counts["dropped"] += 1

    def metrics(self, rss_growth_mb: float, server_ok: bool) -> dict[str, float]:
        """The load metrics of the finished test."""
        counts, params = self.counts, self.params
        return {
            "steer_calls": float(counts["calls"]),
            "calls_per_s": counts["calls"] / params.duration_s,
            "p95_latency_ms": float(np.percentile(self.latencies, 95)) if self.latencies else float("nan"),
            "dropped": float(counts["dropped"]),
            "errors": float(counts["errors"]),
            "malformed_unanswered": float(params.malformed - counts["malformed_answered"]),
            "server_crashes": 0.0 if server_ok else 1.0,
            "rss_growth_mb": rss_growth_mb,
        }


def run_load(params: Any, seed: int) -> dict[str, float]:
    """``connections`` steering clients for ``duration_s`` s plus ``malformed`` bad messages on one more (Maze2D)."""
    from steer_envs.ui.browser import RunningServer

    if params.domain != "maze2d":
        raise ValueError(f"steer-ui: the load test steers maze2d; got domain {params.domain!r}")
    from steer_envs.ui.server import UIConfig

    clients = _LoadClients(params, seed)
    with RunningServer(UIConfig(seed=seed, workers=2, accelerate=params.accelerate)) as server:
        clients.stop_at = time.monotonic() + params.duration_s
        url = server.ws_url
        threads = [threading.Thread(target=clients.steer_loop, args=(i, url)) for i in range(params.connections)]
        threads.append(threading.Thread(target=clients.malformed_loop, args=(url,)))
        for thread in threads:
            thread.start()
        time.sleep(min(params.duration_s / 3.0, 20.0))
        rss_warm = _rss_mb()
        for thread in threads:
            thread.join(params.duration_s + 2 * REPLY_TIMEOUT_S)
        rss_end = _rss_mb()
        alive = server.thread.is_alive()
        # the server still answers a fresh connection after all that
        probe = _Client(server.ws_url)
        answered = probe.ask({"type": "hello"}, ("ready",))["type"] == "ready"
        probe.close()
    return clients.metrics(rss_end - rss_warm, alive and answered)


def run_ui_trial(trial: Trial, params_type: type[SuiteParams]) -> Mapping[str, float | None]:
    """One ``roundtrip`` or ``load`` trial (metrics of the other method are absent)."""
    import torch

    params: Any = params_type.from_json(trial.params)
    torch.set_num_threads(params.threads)  # the process's, as steer-ui --threads sets it
    if trial.method == "roundtrip":
        out = Path(params.screenshot_dir) if params.screenshot_dir else None
        return run_roundtrip(params, trial.seed, out)
    if trial.method == "load":
        return run_load(params, trial.seed)
    raise ValueError(f"steer-ui trials are 'roundtrip' or 'load', got {trial.method!r}")
