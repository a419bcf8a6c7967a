"""``itps-maze2d``: thesis Table 2.1 — steering DP and ACT with sketches in Maze2D-Large.

One trial = one random start location (the seed) x one method (policy x
sampler), run by :func:`~steer_envs.steering.maze.steering_trial`:
the agent is reset at a random free cell, a simulated user draws a sketch from
there (a share of them through walls), and the method samples a batch of 32
plans. Every method of a seed sees the same start, the same sketch and the
same initial noise (ITPS fixed the seed per call). Methods: DP with RS, PR,
OP, BI, GD, SS; ACT with RS, PR, OP.

Metrics per trial (distances divided by the maze extent, ITPS's normalization;
plans scored from the policy's ``exec_start``, i.e. the executed waypoints):

* ``min_l2``: mean per-step L2 distance between the sketch (resampled to the
  plan length) and the plan the sampler *picks*. Every sampler but RS picks the
  batch's closest plan, so this is the batch minimum; RS picks a random plan,
  which is how Table 2.1 has RS's Min L2 (0.27) ~ its Avg L2 (0.28);
* ``avg_l2``: the batch mean of those distances;
* ``collision``: fraction of the batch with a waypoint in a wall cell;
* ``latency_ms`` (timing): wall time of the steering call (batch 32), after a
  per-process warm-up;
* ``ss_gd_latency`` (timing, DP-SS rows): SS's time per call over GD's, the
  medians of ``latency_repeats`` interleaved calls on the trial's input (goal
  <= 4.5; the report's mean over the 100 trials smooths the noise of one pair);
* ``network_evals``: denoiser calls per steering call (DP-BI/GD/SS).

Timings run with ``torch_threads`` intra-op threads per trial process (default
1: the local executor already runs one trial per core, and extra spinning
OpenMP threads per process contend for the cores and distort the SS/GD ratio;
0 keeps torch's default). ``dp_accelerate`` runs the DP's denoiser
``"none"`` (eager), ``"compile"``, ``"trace"`` or ``"onnx"`` (the same plans up
to float32 rounding, faster calls; compilation, tracing and export happen in the
warm-up) or ``"openvino"`` (bfloat16 on a CPU that has it: the fastest, with
plans within bfloat16 rounding;
:meth:`~steer_envs.baselines.diffusion.DiffusionPolicy.accelerate`). The
default, ``"fastest"``, is ``"openvino"`` where OpenVINO is installed, else
``"onnx"`` (or ``"trace"``); ``--param dp_accelerate=none`` gives eager's plans.
The goal on ``latency_ms`` is 250 ms a call (the interactive-latency target for SS
on one core).

Policies come from :func:`steer_envs.baselines.pretrained.load_pretrained`
(``kind`` = ``"dp"`` / ``"act"``, the committed checkpoints); the
``dp_checkpoint`` / ``act_checkpoint`` parameters take another checkpoint
file of ``python -m steer_envs.baselines.training`` (e.g. ``--preset itps``
trained on a GPU), and the ``dp_loader`` / ``act_loader`` parameters name a
registered loader (``pretrained``) or, with ``steer-bench run --allow-import``,
any ``module:function``, so other policies plug in. While a loader's
module, the function or its checkpoint does not exist, the methods of that
policy are skipped with a note. The ``plot`` hook
(:func:`~steer_envs.bench.suites.itps.plots.plot_itps`) draws the
alignment-vs-collision trade-off (thesis Fig. 2.4) and a qualitative grid of
plans per method (thesis Fig. 2.5) from the first ``plot_seeds`` trials.

>>> split_method("DP-SS")
('dp', 'SS')
>>> ItpsParams(through_wall=1.5)
Traceback (most recent call last):
ValueError: itps-maze2d: parameter 'through_wall' must be in [0, 1], got 1.5
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.bench.metrics import MAZE_STEERING_METRICS, table_references
from steer_envs.bench.params import PolicyLoader, SuiteParams
from steer_envs.bench.policies import PRETRAINED_LOADER
from steer_envs.bench.suite import Suite, TrialPlan, TrialResult, register_suite
from steer_envs.bench.table_2_1 import SAMPLERS, table_2_1_findings
from steer_envs.utils.threads import limit_threads

if TYPE_CHECKING:
    from steer_envs.bench.suite import Reference, Trial, TrialRequest

SUITE_NAME = "itps-maze2d"
ENV_ID = "steer_envs/Maze2D-Large-v0"
DP_SAMPLERS: tuple[str, ...] = SAMPLERS
ACT_SAMPLERS: tuple[str, ...] = ("RS", "PR", "OP")
METHODS: tuple[str, ...] = tuple(f"DP-{s}" for s in DP_SAMPLERS) + tuple(f"ACT-{s}" for s in ACT_SAMPLERS)
_DIFFUSION_ONLY = frozenset({"BI", "GD", "SS"})

#: thesis Table 2.1: method -> (Min L2, Avg L2, Collision)
TABLE_2_1: dict[str, tuple[float, float, float]] = {
    "DP-RS": (0.27, 0.28, 0.01),
    "DP-PR": (0.16, 0.28, 0.01),
    "DP-OP": (0.16, 0.28, 0.02),
    "DP-BI": (0.11, 0.14, 0.06),
    "DP-GD": (0.11, 0.18, 0.06),
    "DP-SS": (0.10, 0.12, 0.01),
    "ACT-RS": (0.26, 0.26, 0.16),
    "ACT-PR": (0.26, 0.26, 0.16),
    "ACT-OP": (0.26, 0.26, 0.35),
}


@dataclass(frozen=True)
class ItpsParams(SuiteParams):
    """Parameters of ``itps-maze2d``.

    ``batch`` plans per steering call; ``through_wall`` the share of sketches
    drawn through walls; the first ``plot_seeds`` seeds keep their plans;
    ``torch_threads`` per trial process (0: torch's default);
    ``latency_repeats`` interleaved SS/GD calls; ``{dp,act}_loader`` the
    policy's loader (``pretrained`` or, with ``--allow-import``, any
    ``module:function``) and ``{dp,act}_checkpoint`` a checkpoint file that
    replaces it; ``dp_accelerate`` the DP's inference acceleration
    (``"fastest"``, the default, or another mode of
    :meth:`~steer_envs.baselines.diffusion.DiffusionPolicy.accelerate`);
    ``ddim_steps`` the DP's DDIM steps per plan (0: the checkpoint's 10) and
    ``mcmc_steps`` SS's iterations per noise level (0: its default 4): SS
    calls the network about ``ddim_steps x mcmc_steps`` times.
    """

    suite_name: ClassVar[str] = SUITE_NAME
    batch: int = 32
    through_wall: float = 0.3
    plot_seeds: int = 3
    torch_threads: int = 1
    latency_repeats: int = 1
    dp_loader: PolicyLoader = PRETRAINED_LOADER
    act_loader: PolicyLoader = PRETRAINED_LOADER
    dp_checkpoint: str = ""
    act_checkpoint: str = ""
    dp_accelerate: str = "fastest"
    ddim_steps: int = 0
    mcmc_steps: int = 0

    def __post_init__(self) -> None:
        self.require_at_least(1, "batch")
        self.require_between(0, 100, "ddim_steps")
        self.require_between(0, 64, "mcmc_steps")
        self.require("through_wall", 0.0 <= self.through_wall <= 1.0, "in [0, 1]")
        self.require("torch_threads", self.torch_threads >= 0, ">= 0 (0: torch's default)")
        self.require_at_least(1, "latency_repeats")
        self.require_at_least(0, "plot_seeds")
        if self.dp_accelerate not in ("fastest", "none"):  # the import pulls in torch: only for another value
            from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS

            self.require_in("dp_accelerate", ACCELERATIONS)

    def policy(self, kind: str) -> Any:
        """The policy ``kind`` (``"dp"`` / ``"act"``) these parameters name (cached per process)."""
        if kind not in ("dp", "act"):
            raise ValueError(f"{SUITE_NAME}: policy kind must be 'dp' or 'act', got {kind!r}")
        from steer_envs.baselines.pretrained import shared_policy

        accelerate = self.dp_accelerate if kind == "dp" else "none"
        loader, checkpoint = getattr(self, f"{kind}_loader"), getattr(self, f"{kind}_checkpoint")
        steps = self.ddim_steps if kind == "dp" else 0
        return shared_policy(kind, checkpoint, accelerate, loader=loader, owner="dp_accelerate", steps=steps)


def split_method(method: str) -> tuple[str, str]:
    """``"DP-SS"`` -> ``("dp", "SS")``; ``ValueError`` for an unknown method."""
    if method not in METHODS:
        raise ValueError(f"{SUITE_NAME}: unknown method {method!r}; methods: {', '.join(METHODS)}")
    kind, sampler = method.split("-")
    return kind.lower(), sampler


def _plan_itps(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE
    from steer_envs.core.policy import DiffusionPolicyLike

    params: ItpsParams = suite.resolve_params(request.params, request.trials, base=request.base)
    notes: list[str] = []
    available: dict[str, Any] = {}
    for kind in ("dp", "act"):
        if not any(m is not None and split_method(m)[0] == kind for m in request.methods):
            continue
        try:
            available[kind] = params.policy(kind)
        except POLICY_UNAVAILABLE as exc:
            notes.append(
                f"skipped {kind.upper()} methods: policy not available ({type(exc).__name__}: {exc}); "
                f"train the checkpoint (python -m steer_envs.baselines.training) "
                f"or set --param {kind}_loader=module:function --allow-import"
            )
    trials: list[Trial] = []
    for env in request.envs:
        for method in request.methods:
            assert method is not None
            kind, name = split_method(method)
            if kind not in available:
                continue
            if name in _DIFFUSION_ONLY and not isinstance(available[kind], DiffusionPolicyLike):
                notes.append(f"skipped {method}: the {kind.upper()} policy does not expose its denoiser")
                continue
            trials += [suite.trial(env, method, seed, params) for seed in suite.seed_list(request)]
    return TrialPlan(tuple(trials), tuple(notes))


def run_itps_trial(trial: Trial) -> TrialResult:
    """One start location x one method (see the module docstring)."""
    from steer_envs.steering.maze import steering_trial

    params = ItpsParams.from_json(trial.params)
    with limit_threads(blas_threads=None, torch_threads=params.torch_threads or None):
        kind, sampler = split_method(str(trial.method))
        metrics, extra = steering_trial(
            str(trial.env),
            trial.seed,
            params.policy(kind),
            sampler,
            batch=params.batch,
            through_wall=params.through_wall,
            latency_repeats=params.latency_repeats,
            keep_plans=trial.seed < params.plot_seeds,
            mcmc_steps=params.mcmc_steps or None,
        )
    return TrialResult(metrics, extra)


def _references() -> tuple[Reference, ...]:
    table = {
        method: dict(zip(("min_l2", "avg_l2", "collision"), row, strict=True)) for method, row in TABLE_2_1.items()
    }
    return table_references(table, env=ENV_ID, source="thesis Table 2.1")


ITPS_MAZE2D = register_suite(
    Suite(
        name=SUITE_NAME,
        description="ITPS Maze2D (thesis Table 2.1): sketch steering of DP (6 samplers) and ACT (RS/PR/OP), batch 32.",
        metrics=MAZE_STEERING_METRICS,
        run_trial=run_itps_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=ItpsParams(),
        default_seeds=100,
        generate=_plan_itps,
        references=_references(),
        quick={"plot_seeds": 2},
        quick_seeds=4,
        plot="steer_envs.bench.suites.itps.plots:plot_itps",
        findings=table_2_1_findings,
    )
)
