"""``itps-flow-safety``: ITPS beyond DDPM in Maze2D-Large: a flow policy beside DP, and the safety cost.

Table 2.1's protocol (:func:`~steer_envs.steering.maze.steering_trial`: one
start and one sketch per seed, a batch of 32 plans, distances over the maze
extent, wall collisions, latency) on two policies of the same network and
training budget, Diffusion Policy (``DP-*``, the shipped checkpoint) and the
flow-matching policy (``FLOW-*``, :class:`~steer_envs.baselines.flow.FlowPolicy`
trained by ``scripts/train_maze_flow_checkpoint.sh``, or ``flow_checkpoint``),
each sampler with and without the maze's safety cost (``+safe``: the walls of
the env's ``TaskSpec`` through :func:`~steer_envs.steering.costs.safety_cost`,
weight ``safety_weight``). Both policies run eagerly (no acceleration), so
``latency_ms`` compares their samplers at matched cost per network call
(``flow_steps`` sets the flow's Euler steps: fewer calls per plan). While
no flow checkpoint exists, the ``FLOW-*`` methods are skipped with a note.

>>> split_method("FLOW-SS+safe")
('flow', 'SS', True)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.bench.findings import listing, on_other_policy
from steer_envs.bench.metrics import MAZE_STEERING_METRICS
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Suite, TrialPlan, TrialResult, register_suite
from steer_envs.bench.table_2_1 import table_2_1_findings
from steer_envs.utils.threads import limit_threads

if TYPE_CHECKING:
    from steer_envs.bench.suite import Trial, TrialRequest

SUITE_NAME = "itps-flow-safety"
ENV_ID = "steer_envs/Maze2D-Large-v0"
SAMPLERS: tuple[str, ...] = ("RS", "PR", "OP", "BI", "GD", "SS")
POLICIES: tuple[str, ...] = ("DP", "FLOW")
#: every policy x sampler, and with the safety cost every sampler but RS (which picks at random)
METHODS: tuple[str, ...] = tuple(
    f"{p}-{s}{safe}" for p in POLICIES for s in SAMPLERS for safe in ("", "+safe") if not (s == "RS" and safe)
)


@dataclass(frozen=True)
class FlowSafetyParams(SuiteParams):
    """Parameters of ``itps-flow-safety``.

    ``batch`` plans per call; ``through_wall`` the share of sketches through
    walls; ``safety_weight`` the safety cost's weight in the ``+safe``
    methods; ``flow_checkpoint`` the flow policy's file (default: the one the
    recipe writes into the package); ``flow_steps`` its Euler steps per plan (0:
    the checkpoint's own, DP's 10 DDIM steps; fewer steer faster);
    ``dp_checkpoint`` another DP file (default: the shipped DP);
    ``torch_threads`` per trial process.
    """

    suite_name: ClassVar[str] = SUITE_NAME
    batch: int = 32
    through_wall: float = 0.3
    safety_weight: float = 1.0
    flow_checkpoint: str = ""
    flow_steps: int = 0
    dp_checkpoint: str = ""
    torch_threads: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "batch")
        self.require("through_wall", 0.0 <= self.through_wall <= 1.0, "in [0, 1]")
        self.require("safety_weight", self.safety_weight > 0, "> 0")
        self.require("torch_threads", self.torch_threads >= 0, ">= 0 (0: torch's default)")
        self.require_between(0, 1000, "flow_steps")

    def policy(self, kind: str) -> Any:
        """The DP (``"dp"``) or flow (``"flow"``, with ``flow_steps`` Euler steps) policy, loaded once per process."""
        from steer_envs.baselines.pretrained import shared_policy

        if kind == "dp":
            return shared_policy("dp", self.dp_checkpoint)
        return shared_policy(self.flow_checkpoint or _trained_flow(), steps=self.flow_steps)


#: where ``scripts/train_maze_flow_checkpoint.sh`` writes the Maze2D flow policy (inside the package)
FLOW_FILE = ("checkpoints", "maze2d_large", "flow.safetensors")


def _trained_flow() -> str:
    """The Maze2D flow policy the recipe wrote; ``FileNotFoundError`` (the suite skips ``FLOW-*``) before it has."""
    from importlib import resources

    path = resources.files("steer_envs.baselines").joinpath(*FLOW_FILE)
    if not path.is_file():
        raise FileNotFoundError(
            "no Maze2D flow policy yet: train it with scripts/train_maze_flow_checkpoint.sh or set flow_checkpoint"
        )
    return str(path)


def split_method(method: str) -> tuple[str, str, bool]:
    """``"FLOW-SS+safe"`` -> ``("flow", "SS", True)``; ``ValueError`` for an unknown method."""
    if method not in METHODS:
        raise ValueError(f"{SUITE_NAME}: unknown method {method!r}; methods: {', '.join(METHODS)}")
    policy, rest = method.split("-")
    sampler, _, safe = rest.partition("+")
    return policy.lower(), sampler, bool(safe)


def _plan(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE

    params: FlowSafetyParams = suite.resolve_params(request.params, request.trials, base=request.base)
    notes: list[str] = []
    available = set()
    for kind in ("dp", "flow"):
        if not any(m is not None and split_method(m)[0] == kind for m in request.methods):
            continue
        try:
            params.policy(kind)
            available.add(kind)
        except POLICY_UNAVAILABLE as exc:
            notes.append(f"skipped {kind.upper()} methods: policy not available ({type(exc).__name__}: {exc})")
    trials: list[Trial] = [
        suite.trial(env, method, seed, params)
        for env in request.envs
        for method in request.methods
        if method is not None and split_method(method)[0] in available
        for seed in suite.seed_list(request)
    ]
    return TrialPlan(tuple(trials), tuple(notes))


def run_flow_safety_trial(trial: Trial) -> TrialResult:
    """One start location x one method (see the module docstring)."""
    from steer_envs.steering.maze import steering_trial

    params = FlowSafetyParams.from_json(trial.params)
    kind, sampler, safe = split_method(str(trial.method))
    with limit_threads(blas_threads=None, torch_threads=params.torch_threads or None):
        metrics, extra = steering_trial(
            str(trial.env),
            trial.seed,
            params.policy(kind),
            sampler,
            batch=params.batch,
            through_wall=params.through_wall,
            safety_weight=params.safety_weight if safe else 0.0,
        )
    return TrialResult(metrics, extra)


def _safety_findings(table: Any, policy: str) -> list[Finding]:
    findings = []
    for sampler in ("GD", "SS"):
        plain, safe = f"{policy}-{sampler}", f"{policy}-{sampler}+safe"
        coll = table.means("collision", [plain, safe])
        min_l2 = table.means("min_l2", [plain, safe])
        claim = f"{safe} collides less than {plain} at equal or better Min L2 (within 0.005)"
        if coll is None or min_l2 is None:
            findings.append(Finding(claim, None))
            continue
        holds = coll[safe] < coll[plain] and min_l2[safe] <= min_l2[plain] + 0.005
        detail = f"collision {listing(coll, '.3f')}; Min L2 {listing(min_l2, '.3f')}"
        findings.append(Finding(claim, holds, detail))
    return findings


def _flow_findings(table: Any) -> list[Finding]:
    claim = "the flow policy's SS call is no slower than DP's"
    latency = table.means("latency_ms", ["DP-SS", "FLOW-SS"])
    if latency is None:
        return [Finding(claim, None)]
    ratio = latency["FLOW-SS"] / latency["DP-SS"]
    speed = Finding(claim, ratio <= 1.05, f"FLOW-SS / DP-SS latency {ratio:.2f}")
    return [*on_other_policy(table_2_1_findings, table, "FLOW-", "flow policy"), speed]


def flow_safety_findings(table: Any) -> list[Finding]:
    """The safety cost helps GD and SS of each policy; Table 2.1's findings on the flow; its speed against DP's."""
    return [*_safety_findings(table, "DP"), *_safety_findings(table, "FLOW"), *_flow_findings(table)]


ITPS_FLOW_SAFETY = register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "ITPS beyond DDPM (Maze2D-Large): DP vs a flow-matching policy of the same network and training, "
            "each sampler with and without the walls' safety cost; seeds are start locations."
        ),
        metrics=MAZE_STEERING_METRICS,
        run_trial=run_flow_safety_trial,
        envs=(ENV_ID,),
        methods=METHODS,
        params=FlowSafetyParams(),
        default_seeds=100,
        generate=_plan,
        findings=flow_safety_findings,
    )
)
