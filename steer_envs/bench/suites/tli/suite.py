"""TLI / LTL-DS suites (thesis ch. 3): single-mode invariance, soup scooping under pushes, LPV-DS fit time.

* ``tli-single-mode`` (thesis Fig. 3.5 table): one trial = one random convex
  mode (the seed is ConvexMode-v0's ``layout_seed``; the thesis: 50 modes) x
  one policy (BC, BC+mod, DS, DS+mod), run at the three start-noise levels
  (sigma 0 / 1 / 5 workspace units = the thesis's 0 / 5 / 30 %) with
  ``n_starts`` starts each, through
  :func:`~steer_envs.bench.suites.tli.protocol.single_mode_trial`. Success is
  reported in %, with the thesis's numbers beside; ``cuts_30`` is the number of
  cuts the cut loop added at the large noise (thesis: DS reaches 100 % within
  four). The first ``plot_seeds`` layouts keep rollouts for the Fig. 3.4-style
  plot (:func:`~steer_envs.bench.suites.tli.plots.plot_single_mode`).
* ``tli-scoop`` (thesis §3.7.2): one trial = one experiment (the thesis ran
  10) of LTL-DS soup scooping under random pushes, without (``ltl-ds``) and with
  (``ltl-ds+mod``) modulation, through
  :func:`~steer_envs.bench.suites.tli.robustness.scoop_trial`: eventual success
  (%), invariance failures (= discrete loop iterations), cuts, steps.
* ``tli-ds-fit``: wall time of an LPV-DS fit of 3 demos x 200 points in 2D
  (goal < 5 s, :func:`~steer_envs.baselines.lpv_ds.lpvds.benchmark_fit_time`).

Each suite's parameters are a dataclass here (:class:`SingleModeParams`,
:class:`ScoopParams`, :class:`DsFitParams`). Trials run with one BLAS and one
torch thread (the fits and rollouts are tiny; extra threads only add
contention on a shared machine).

>>> SingleModeParams(n_starts=30).to_json()["n_starts"]
30
>>> ScoopParams(demos="typed")
Traceback (most recent call last):
ValueError: tli-scoop: parameter 'demos' must be one of ('drawn', 'expert'), got 'typed'
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from steer_envs.bench.metrics import table_references
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, Trial, TrialResult, register_suite
from steer_envs.bench.trials import check_trial
from steer_envs.utils.threads import single_threaded

CONVEX_ENV = "steer_envs/ConvexMode-v0"
SCOOP_ENV = "steer_envs/SoupScoop-v0"
SINGLE_MODE_METHODS: tuple[str, ...] = ("bc", "bc+mod", "ds", "ds+mod")
SCOOP_METHODS: tuple[str, ...] = ("ltl-ds", "ltl-ds+mod")
#: metric suffix (% of the workspace) -> start-noise sigma in workspace units (the workspace is 16 wide).
NOISE_LEVELS: Mapping[str, float] = {"0": 0.0, "5": 1.0, "30": 5.0}
#: where demonstrations come from: hand-drawn-like curves or the scripted expert
DEMO_SOURCES: tuple[str, ...] = ("drawn", "expert")
#: thesis Fig. 3.5 table (success %, noise 0 / 5 / 30 %); the same numbers as ``protocol.THESIS_SUCCESS``.
THESIS_SINGLE_MODE: Mapping[str, tuple[float, float, float]] = {
    "bc": (88.9, 72.4, 58.6),
    "bc+mod": (91.9, 83.6, 76.0),
    "ds": (100.0, 97.0, 86.9),
    "ds+mod": (100.0, 100.0, 100.0),
}


# ------------------------------------------------------------ tli-single-mode
@dataclass(frozen=True)
class SingleModeParams(SuiteParams):
    """Parameters of ``tli-single-mode``.

    ``n_starts`` starts per noise level; ``max_cuts`` cuts the cut loop may add
    (+mod); ``bc_epochs`` of BC training; ``demos`` from :data:`DEMO_SOURCES`;
    ``cut_sigma`` a separate start noise for the cut loop (``None``: the
    level's own); the first ``plot_seeds`` layouts keep their rollouts.
    """

    suite_name: ClassVar[str] = "tli-single-mode"
    n_starts: int = 100
    max_cuts: int = 4
    bc_epochs: int = 4000
    demos: str = "drawn"
    cut_sigma: float | None = None
    plot_seeds: int = 1

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_starts", "bc_epochs")
        self.require_at_least(0, "max_cuts", "plot_seeds")
        self.require_in("demos", DEMO_SOURCES)


def run_single_mode_trial(trial: Trial) -> TrialResult:
    """One layout x one policy at the three noise levels (see the module docstring)."""
    from steer_envs.bench.suites.tli.protocol import POLICY_KINDS, single_mode_trial

    check_trial(trial, methods=POLICY_KINDS)
    params = SingleModeParams.from_json(trial.params)
    kind, cut_sigma, kwargs = str(trial.method), params.cut_sigma, params.kwargs(without=("plot_seeds",))
    metrics: dict[str, float | None] = {}
    per_noise: dict[str, Any] = {}
    figures: dict[str, Any] = {}
    with single_threaded():
        for label, sigma in NOISE_LEVELS.items():
            res = single_mode_trial(trial.seed, sigma, kind, seed=trial.seed, **kwargs)
            metrics[f"success_{label}"] = 100.0 * res["success_rate"]
            per_noise[label] = {
                k: res[k]
                for k in ("invariance_failure_rate", "reachability_failure_rate", "num_cuts", "cuts_until_invariant")
            }
            per_noise[label]["cut_round_success"] = res["cut_round_success"]
            if trial.seed < params.plot_seeds and cut_sigma is None:
                from steer_envs.bench.suites.tli.plots import single_mode_figure_data

                shown = params.kwargs(without=("plot_seeds", "cut_sigma"))  # cut_sigma None: the batch's own cuts
                figures[str(sigma)] = single_mode_figure_data(
                    trial.seed, sigma, kind, res["n_demos"], seed=trial.seed, **shown
                )
    mod = kind.endswith("+mod")
    metrics["cuts_5"] = float(per_noise["5"]["num_cuts"]) if mod else None
    metrics["cuts_30"] = float(per_noise["30"]["num_cuts"]) if mod else None
    metrics["inv_fail_30"] = 100.0 * per_noise["30"]["invariance_failure_rate"]
    metrics["reach_fail_30"] = 100.0 * per_noise["30"]["reachability_failure_rate"]
    extra: dict[str, Any] = {"n_demos": res["n_demos"], "per_noise": per_noise}
    if figures:
        extra["figure"] = figures
    return TrialResult(metrics, extra)


def single_mode_findings(table: Any) -> list[Finding]:
    """Fig. 3.5's claims: modulation helps BC and never hurts DS; DS+mod succeeds from every start."""
    levels = list(NOISE_LEVELS)
    means = {lvl: table.means(f"success_{lvl}", SINGLE_MODE_METHODS) for lvl in levels}
    ready = all(v is not None for v in means.values())

    def row(method: str) -> str:
        return f"{method} " + "/".join(f"{means[lvl][method]:.1f}" for lvl in levels)  # type: ignore[index]

    claims = (  # (claim, test on one level's means, levels, methods shown)
        ("BC+mod succeeds more often than BC at 5 % and 30 % noise", lambda v: v["bc+mod"] > v["bc"], ("5", "30"),
         ("bc", "bc+mod")),
        ("DS+mod succeeds at least as often as DS at every noise level", lambda v: v["ds+mod"] >= v["ds"], levels,
         ("ds", "ds+mod")),
        ("DS+mod succeeds from every start at every noise level", lambda v: v["ds+mod"] >= 100.0 - 1e-9, levels,
         ("ds+mod",)),
    )  # fmt: skip
    return [
        Finding(claim, all(test(means[lvl]) for lvl in at), "; ".join(map(row, shown)))
        if ready
        else Finding(claim, None)
        for claim, test, at, shown in claims
    ]


def _single_mode_references() -> tuple[Reference, ...]:
    success = {m: {f"success_{label}": v for label, v in zip(NOISE_LEVELS, values, strict=True)}
               for m, values in THESIS_SINGLE_MODE.items()}  # fmt: skip
    cuts = Reference("cuts_30", 4.0, env=CONVEX_ENV, method="ds+mod", source="thesis Fig. 3.5 (cuts to 100 %)")
    return (*table_references(success, env=CONVEX_ENV, source="thesis Fig. 3.5"), cuts)


TLI_SINGLE_MODE = register_suite(
    Suite(
        name="tli-single-mode",
        description=(
            "TLI single-mode study (thesis Fig. 3.5): success (%) of BC, BC+mod, DS, DS+mod on random convex modes "
            "at start noise 0/5/30 % of the workspace; seeds are layouts."
        ),
        metrics=(
            Metric("success_0", "success (%), starts on the demonstrations", fmt=".1f"),
            Metric("success_5", "success (%), start noise sigma 1 (5 % of the workspace)", fmt=".1f"),
            Metric("success_30", "success (%), start noise sigma 5 (30 % of the workspace)", fmt=".1f"),
            Metric("cuts_5", "cuts learned at 5 % noise (+mod only)", higher_is_better=False, fmt=".2f"),
            Metric("cuts_30", "cuts learned at 30 % noise (+mod only)", higher_is_better=False, fmt=".2f"),
            Metric("inv_fail_30", "starts that left the mode (%), 30 % noise", higher_is_better=False, fmt=".1f"),
            Metric(
                "reach_fail_30",
                "starts that stayed but missed the attractor (%), 30 % noise",
                higher_is_better=False,
                fmt=".1f",
            ),
        ),
        run_trial=run_single_mode_trial,
        envs=(CONVEX_ENV,),
        methods=SINGLE_MODE_METHODS,
        params=SingleModeParams(),
        trials_param="n_starts",
        default_seeds=50,
        references=_single_mode_references(),
        quick={"n_starts": 30, "bc_epochs": 500, "plot_seeds": 1},
        quick_seeds=2,
        plot="steer_envs.bench.suites.tli.plots:plot_single_mode",
        findings=single_mode_findings,
    )
)


# ------------------------------------------------------------------ tli-scoop
@dataclass(frozen=True)
class ScoopParams(SuiteParams):
    """Parameters of ``tli-scoop``.

    ``n_perturbations`` pushes at steps ``1..push_window`` of an episode of at
    most ``max_steps``, each up to ``magnitude`` long; ``demos`` from
    :data:`DEMO_SOURCES`; ``ds_eps`` the LPV-DS stability margin; the first
    ``plot_seeds`` experiments keep their rollouts.
    """

    suite_name: ClassVar[str] = "tli-scoop"
    n_perturbations: int = 5
    push_window: int = 800
    max_steps: int = 5000
    magnitude: float = 16.0
    demos: str = "drawn"
    ds_eps: float = 1.0
    plot_seeds: int = 2

    def __post_init__(self) -> None:
        self.require_at_least(0, "n_perturbations", "plot_seeds")
        self.require_at_least(1, "max_steps")
        self.require_in("demos", DEMO_SOURCES)


def run_scoop_trial(trial: Trial) -> TrialResult:
    """One soup-scooping experiment under pushes, without or with modulation."""
    from steer_envs.bench.suites.tli.robustness import scoop_trial

    check_trial(trial, methods=SCOOP_METHODS)
    params = ScoopParams.from_json(trial.params)
    record = trial.seed < params.plot_seeds
    with single_threaded():
        modulation, kwargs = trial.method == "ltl-ds+mod", params.kwargs(without=("plot_seeds",))
        res = scoop_trial(trial.seed, modulation, **kwargs, record=record)
    metrics = {
        "success": 100.0 * res["success"],
        "loops": float(res["invariance_failures"]),
        "mode_reentries": float(res["mode_reentries"]),
        "num_cuts": float(res["num_cuts"]),
        "pushes": float(res["pushes"]),
        "steps": float(res["steps"]),
    }
    extra: dict[str, Any] = {"n_demos": res["n_demos"], "fit_seconds": res["fit_seconds"]}
    if record:
        from steer_envs.bench.suites.tli.plots import scoop_figure_data

        extra["figure"] = scoop_figure_data(res)
    return TrialResult(metrics, extra)


TLI_SCOOP = register_suite(
    Suite(
        name="tli-scoop",
        description=(
            "TLI soup scooping (thesis 3.7.2): LTL-DS under random pushes (uniform direction, up to the workspace "
            "size), without / with modulation: eventual success and discrete loops; seeds are experiments."
        ),
        metrics=(
            Metric("success", "eventual success (%) within max_steps", fmt=".0f"),
            Metric("loops", "invariance failures = discrete mode-loop iterations", higher_is_better=False, fmt=".1f"),
            Metric("mode_reentries", "entries into an already visited mode", higher_is_better=False, fmt=".1f"),
            Metric("num_cuts", "cuts learned in the episode", higher_is_better=False, fmt=".1f"),
            Metric("pushes", "pushes applied before the task was done", fmt=".1f"),
            Metric("steps", "episode steps (dt = 0.01)", higher_is_better=False, fmt=".0f"),
        ),
        run_trial=run_scoop_trial,
        envs=(SCOOP_ENV,),
        methods=SCOOP_METHODS,
        params=ScoopParams(),
        trials_param="n_perturbations",
        default_seeds=10,
        references=(Reference("success", 100.0, env=SCOOP_ENV, method="ltl-ds+mod", source="thesis 3.7.2 (10/10)"),),
        quick={"max_steps": 3000, "plot_seeds": 1},
        quick_seeds=2,
        plot="steer_envs.bench.suites.tli.plots:plot_scoop",
    )
)


# ----------------------------------------------------------------- tli-ds-fit
@dataclass(frozen=True)
class DsFitParams(SuiteParams):
    """Parameters of ``tli-ds-fit``: the size of the fitted data set."""

    suite_name: ClassVar[str] = "tli-ds-fit"
    n_demos: int = 3
    n_points: int = 200

    def __post_init__(self) -> None:
        self.require_at_least(1, "n_demos", "n_points")


def run_ds_fit_trial(trial: Trial) -> dict[str, float]:
    """Wall time of one LPV-DS fit of ``n_demos`` x ``n_points`` curved 2D demonstrations."""
    from steer_envs.baselines.lpv_ds.lpvds import benchmark_fit_time

    params = DsFitParams.from_json(trial.params)
    with single_threaded():
        out = benchmark_fit_time(params.n_demos, params.n_points, seed=trial.seed)
    return {k: float(out[k]) for k in ("fit_seconds", "n_components", "worst_margin")}


TLI_DS_FIT = register_suite(
    Suite(
        name="tli-ds-fit",
        description="LPV-DS fit time of 3 demos x 200 points in 2D (goal < 5 s) and its stability margin.",
        metrics=(
            Metric(
                "fit_seconds", "LPV-DS fit wall time (s)", kind="timing", higher_is_better=False, fmt=".2f", goal=5.0
            ),
            Metric("n_components", "GMM components chosen by BIC", fmt=".0f"),
            Metric("worst_margin", "max eig of A_k^T P + P A_k (must be < 0)", higher_is_better=False, fmt=".2g"),
        ),
        run_trial=run_ds_fit_trial,
        params=DsFitParams(),
        default_seeds=3,
        quick={"n_points": 200},
        quick_seeds=1,
    )
)
