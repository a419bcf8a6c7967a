"""``itps-latency``: how long a steering call takes on this CPU, on every acceleration path, side by side.

One trial = one sampler x one inference path of the shipped Maze2D-Large DP
through a :class:`~steer_envs.ui.session.Session` (what steer-ui runs per
sketch): the median of ``calls`` calls after ``warmup`` untimed ones
(:func:`~steer_envs.ui.latency.steering_latency`), split into network, sampler
and other. Methods are ``<sampler>-<path>``: samplers RS, GD and SS at batch
``batch``; paths ``eager`` (float32 PyTorch), ``trace``, ``onnx`` (ONNX
Runtime), ``openvino-f32`` / ``-bf16`` / ``-int8`` (NNCF's post-training
quantization) and ``fastest`` (the shipped default: what ``"fastest"`` picks on
this CPU, named in the trial's extras). The run's notes name the CPU and its
instruction sets, since latency is a property of the CPU; run it on an idle
machine with ``--workers 1``. ``ddim_steps`` and ``mcmc_steps`` change the
network calls per steer (0: the checkpoint's 10 DDIM steps, SS's 4 MCMC steps).

>>> split_method("SS-openvino-int8")
('SS', 'openvino-int8')
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.bench.findings import judge
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Suite, TrialPlan, TrialResult, register_suite
from steer_envs.utils.threads import limit_threads

if TYPE_CHECKING:
    from steer_envs.bench.suite import Trial, TrialRequest

SUITE_NAME = "itps-latency"
ENV_ID = "steer_envs/Maze2D-Large-v0"
SAMPLERS: tuple[str, ...] = ("RS", "GD", "SS")
#: inference path -> the DP's acceleration mode
PATHS: dict[str, str] = {
    "eager": "none",
    "trace": "trace",
    "onnx": "onnx",
    "openvino-f32": "openvino-f32",
    "openvino-bf16": "openvino-bf16",
    "openvino-int8": "openvino-int8",
    "fastest": "fastest",
}
METHODS: tuple[str, ...] = tuple(f"{s}-{p}" for s in SAMPLERS for p in PATHS)
#: SS at batch 32 through a Session within this many ms: on a CPU with AMX, and on one without
TARGET_MS = {"amx": 100.0, "other": 150.0}


@dataclass(frozen=True)
class LatencyParams(SuiteParams):
    """Parameters of ``itps-latency``: ``batch`` plans per call, ``calls`` timed after ``warmup`` untimed,
    ``threads`` torch threads (1: one core, the target's setting), ``ddim_steps`` / ``mcmc_steps`` (0: defaults)."""

    suite_name: ClassVar[str] = SUITE_NAME
    batch: int = 32
    calls: int = 8
    warmup: int = 2
    threads: int = 1
    ddim_steps: int = 0
    mcmc_steps: int = 0

    def __post_init__(self) -> None:
        self.require_between(1, 1024, "batch")
        self.require_between(1, 1000, "calls")
        self.require_between(0, 1000, "warmup")
        self.require_between(1, 256, "threads")
        self.require_between(0, 100, "ddim_steps")
        self.require_between(0, 64, "mcmc_steps")


def split_method(method: str) -> tuple[str, str]:
    """``"SS-openvino-int8"`` -> ``("SS", "openvino-int8")``; ``ValueError`` for an unknown method."""
    if method not in METHODS:
        raise ValueError(f"{SUITE_NAME}: unknown method {method!r}; methods: {', '.join(METHODS)}")
    sampler, path = method.split("-", 1)
    return sampler, path


def _plan(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.utils.cpu import cpu_summary

    params = suite.resolve_params(request.params, request.trials, base=request.base)
    return TrialPlan(suite.every_trial(request), (f"CPU: {cpu_summary()}; {params.threads} torch thread(s)",))


def run_latency_trial(trial: Trial) -> TrialResult:
    """Time one sampler on one inference path (see the module docstring)."""
    from steer_envs.baselines.pretrained import shared_policy
    from steer_envs.ui.latency import steering_latency
    from steer_envs.ui.session import Session
    from steer_envs.ui.settings import SteerSettings
    from steer_envs.users.sketcher import SketchUser
    from steer_envs.utils.cpu import cpu_summary, isa_features

    params = LatencyParams.from_json(trial.params)
    sampler, path = split_method(str(trial.method))
    with limit_threads(blas_threads=1, torch_threads=params.threads):
        policy = shared_policy("dp", "", PATHS[path], steps=params.ddim_steps)
        settings = SteerSettings(sampler, params.batch, mcmc_steps=params.mcmc_steps or None)
        session = Session("maze2d", policy=policy, settings=settings, seed=trial.seed, threads=params.threads)
        try:
            maze: Any = session.env.unwrapped
            sketch = SketchUser(maze.grid, through_wall=0.0, seed=trial.seed).draw(session.state)
            latency = steering_latency(session, sketch.sketch, calls=params.calls, warmup=params.warmup)
        finally:
            session.env.close()
    target = TARGET_MS["amx" if isa_features()["amx"] else "other"]
    metrics: dict[str, float | None] = {
        "latency_ms": latency.total,
        "network_ms": latency.network,
        "sampler_ms": latency.sampler,
        "other_ms": latency.other,
        "network_evals": latency.network_evals,
        "within_target": float(latency.total <= target) if sampler == "SS" else None,
    }
    extra = {"cpu": cpu_summary(), "acceleration": getattr(policy, "acceleration", "none"), "target_ms": target}
    return TrialResult(metrics, extra)


def latency_findings(table: Any) -> list[Finding]:
    """SS on the shipped default path within the target; the default's speed-up over eager float32."""
    default, eager = "SS-fastest", "SS-eager"
    return [
        judge(
            f"the shipped default steers SS (batch 32) within {TARGET_MS['other']:.0f} ms a call "
            f"({TARGET_MS['amx']:.0f} ms on a CPU with AMX)",
            table.means("within_target", [default]),
            lambda v: v[default] >= 1.0,
            lambda v: f"SS {table.means('latency_ms', [default])[default]:.0f} ms",
        ),
        judge(
            "the shipped default is faster than eager float32 (SS)",
            table.means("latency_ms", [default, eager]),
            lambda v: v[default] < v[eager],
            lambda v: f"default / eager {v[default] / v[eager]:.2f} ({v[default]:.0f} vs {v[eager]:.0f} ms)",
        ),
    ]


def _timing(name: str, description: str) -> Metric:
    return Metric(name, description, kind="timing", higher_is_better=False, fmt=".0f")


ITPS_LATENCY = register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "Steering latency of the shipped Maze2D DP through a Session on this CPU: RS / GD / SS at batch 32 on "
            "every acceleration path (eager, trace, ONNX Runtime, OpenVINO f32 / bf16 / int8, the shipped default)."
        ),
        metrics=(
            _timing("latency_ms", "median ms per steering call (batch 32)"),
            _timing("network_ms", "of which the network"),
            _timing("sampler_ms", "of which the sampler"),
            _timing("other_ms", "of which the session around it"),
            Metric("network_evals", "network calls per steering call", kind="timing", fmt=".0f"),
            Metric("within_target", "SS within the target latency on this CPU (1 / 0)", fmt=".0f"),
        ),
        run_trial=run_latency_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=LatencyParams(),
        default_seeds=1,
        generate=_plan,
        findings=latency_findings,
    )
)
