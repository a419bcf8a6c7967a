"""``steer-ui``: the browser UI's steering round trip (network / sampler / drawing) and a bounded load test.

Method ``roundtrip``: the ``domain``'s gesture (``maze2d``: a sketch; the
other steered domains: a click; the push domains: a drag of the agent) sent ->
plans (or the pushed frame) drawn, with the domain's own sampler and batch
unless ``sampler`` / ``batch`` are set (Maze2D: SS at batch 32), in a
headless chromium when one is installed; the trial's extras name the CPU.
Method ``load``: 8 connections steering Maze2D for 60 s beside 1,000 malformed
messages, on 127.0.0.1 only (see :mod:`steer_envs.bench.suites.ui.protocol`).
``steer-bench run steer-ui --method roundtrip --param domain=arm-scoop`` measures
one domain.

>>> UIParams(duration_s=5.0).to_json()["duration_s"]
5.0
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.findings import cell_means
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Suite, Trial, TrialResult, register_suite

METHODS: tuple[str, ...] = ("roundtrip", "load")
#: the budgets: a round trip under 0.5 s, memory "flat" = this much growth at most
TARGET_MS = 500.0
FLAT_MB = 64.0
#: the first steering call after the page says ready may take at most this many times a later one
FIRST_RATIO = 1.5


@dataclass(frozen=True)
class UIParams(SuiteParams):
    """Parameters of ``steer-ui``: the steering settings, round trips, and the load test's size."""

    suite_name: ClassVar[str] = "steer-ui"
    domain: str = "maze2d"
    #: "" / 0: the domain's own (Maze2D: SS at batch 32; BlockStack and Kitchen: GD at batch 16)
    sampler: str = ""
    batch: int = 0
    mcmc_steps: int | None = None
    accelerate: str = "fastest"
    threads: int = 1
    roundtrips: int = 10
    target_ms: float = TARGET_MS
    browser: str = "auto"
    screenshot_dir: str = ""
    connections: int = 8
    duration_s: float = 60.0
    malformed: int = 1000
    cache_dir: str = ""

    def __post_init__(self) -> None:
        from steer_envs.ui.domains import DOMAINS

        self.require_in("domain", tuple(DOMAINS))
        self.require_in("sampler", ("", "RS", "PR", "OP", "BI", "GD", "SS"))
        self.require_in("browser", ("auto", "yes", "no"))
        from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS  # here: it imports torch

        self.require_in("accelerate", ACCELERATIONS)
        self.require_at_least(0, "batch")
        self.require_at_least(1, "roundtrips", "connections", "threads")
        self.require_at_most(64, "threads")
        self.require_at_most(256, "batch")
        self.require_at_most(64, "connections")
        self.require_at_least(0, "malformed")
        self.require_at_most(100_000, "malformed")
        self.require("duration_s", 1.0 <= self.duration_s <= 3600.0, "in [1, 3600] seconds")
        self.require("target_ms", self.target_ms > 0, "> 0")
        self.require("mcmc_steps", self.mcmc_steps is None or 1 <= self.mcmc_steps <= 1000, "None or in [1, 1000]")


ROUNDTRIP_METRICS = (
    "roundtrip_ms", "network_ms", "sampler_ms", "push_ms", "server_ms", "transfer_ms", "draw_ms", "under_target",
    "first_ratio",
)  # fmt: skip
LOAD_METRICS = (
    "steer_calls",
    "calls_per_s",
    "p95_latency_ms",
    "dropped",
    "errors",
    "malformed_unanswered",
    "server_crashes",
    "rss_growth_mb",
)


def run_steer_ui_trial(trial: Trial) -> TrialResult:
    """One trial (the other method's metrics are ``None``); its extras: the domain and the CPU's name."""
    from steer_envs.bench.suites.ui.protocol import run_ui_trial
    from steer_envs.utils.cpu import cpu_name

    values = run_ui_trial(trial, UIParams)
    metrics = {name: values.get(name) for name in (*ROUNDTRIP_METRICS, *LOAD_METRICS, "browser")}
    return TrialResult(metrics, {"domain": UIParams.from_json(trial.params).domain, "cpu": cpu_name()})


def ui_findings(table: Any) -> list[Finding]:
    """The checks: round trip under 0.5 s; load without drops, errors, crashes or memory growth."""
    out = []
    rtt = cell_means(table, "roundtrip", ("roundtrip_ms", "network_ms", "sampler_ms", "push_ms", "draw_ms"))
    claim = f"a steering round trip (input sent -> plans or pushed frame drawn) takes under {TARGET_MS:.0f} ms"
    if rtt["roundtrip_ms"] is None:
        out.append(Finding(claim, None))
    else:
        if rtt["network_ms"] is not None:
            split = "network {network_ms:.0f} + sampler {sampler_ms:.0f}"
        else:
            split = "push {push_ms:.0f}"
        detail = "round trip {roundtrip_ms:.0f} ms = " + split + " + drawing {draw_ms:.1f} + transfer/encoding"
        out.append(Finding(claim, rtt["roundtrip_ms"] < TARGET_MS, detail.format_map(rtt)))
    first = cell_means(table, "roundtrip", ("first_ratio",))["first_ratio"]
    claim = f"the first steering call after ready takes at most {FIRST_RATIO:.1f}x the later ones (warmed up)"
    out.append(Finding(claim, None) if first is None else Finding(claim, first <= FIRST_RATIO, f"{first:.2f}x"))
    load = cell_means(table, "load", LOAD_METRICS)
    claim = "concurrent connections steer without a drop, an error or a crash; every malformed message is answered"
    if load["dropped"] is None:
        out.append(Finding(claim, None))
    else:
        bad = load["dropped"] + load["errors"] + load["server_crashes"] + load["malformed_unanswered"]
        detail = (
            "{steer_calls:.0f} steering calls ({calls_per_s:.2f}/s, p95 {p95_latency_ms:.0f} ms), dropped "
            "{dropped:.0f}, errors {errors:.0f}, crashes {server_crashes:.0f}, unanswered malformed "
            "{malformed_unanswered:.0f}"
        )
        out.append(Finding(claim, bad == 0, detail.format_map(load)))
        claim = f"memory stays flat under load (growth under {FLAT_MB:.0f} MiB after warm-up)"
        out.append(Finding(claim, load["rss_growth_mb"] < FLAT_MB, f"{load['rss_growth_mb']:+.1f} MiB"))
    return out


STEER_UI = register_suite(
    Suite(
        name="steer-ui",
        description="steer-ui: steering round trip split (network / sampler / drawing) and a bounded load test.",
        metrics=(
            Metric("roundtrip_ms", "input sent -> plans / frame drawn (median, ms)", "timing", False, ".0f", TARGET_MS),
            Metric("network_ms", "policy network time per call (median, ms)", "timing", False, ".0f"),
            Metric(
                "first_ratio",
                "the first steering call after the page says ready over the median later one",
                "timing",
                False,
                ".2f",
                FIRST_RATIO,
            ),
            Metric("sampler_ms", "sampler time outside the network (median, ms)", "timing", False, ".0f"),
            Metric("push_ms", "a push domain's push: perturb and the controller (median, ms)", "timing", False, ".0f"),
            Metric("server_ms", "server time per call incl. encoding (median, ms)", "timing", False, ".0f"),
            Metric("transfer_ms", "round trip minus server and drawing (ms)", "timing", False, ".1f"),
            Metric("draw_ms", "drawing the plans on the page (median, ms)", "timing", False, ".1f"),
            Metric("under_target", "round trip under the target (%)", "timing", True, ".0f"),
            Metric("steer_calls", "steering calls answered under load", "timing", True, ".0f"),
            Metric("calls_per_s", "steering calls per second under load", "timing", True, ".2f"),
            Metric("p95_latency_ms", "95th percentile latency under load (ms)", "timing", False, ".0f"),
            Metric("dropped", "connections dropped", "value", False, ".0f", 0.0),
            Metric("errors", "error replies to valid steering requests", "value", False, ".0f", 0.0),
            Metric("malformed_unanswered", "malformed messages without an error reply", "value", False, ".0f", 0.0),
            Metric("server_crashes", "server crashes", "value", False, ".0f", 0.0),
            Metric("rss_growth_mb", "resident memory growth after warm-up (MiB)", "timing", False, ".1f", FLAT_MB),
            Metric("browser", "measured in a headless chromium (1) or a socket client (0)", "value", True, ".0f"),
        ),
        run_trial=run_steer_ui_trial,
        methods=METHODS,
        params=UIParams(),
        trials_param="roundtrips",
        default_seeds=1,
        quick={"roundtrips": 3, "connections": 2, "duration_s": 5.0, "malformed": 100},
        quick_seeds=1,
        findings=ui_findings,
    )
)
