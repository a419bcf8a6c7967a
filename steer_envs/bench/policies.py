"""Suites whose every trial needs one frozen policy: plan them all, or none with a note while it is missing.

:func:`plan_with_policy` (or :func:`policy_planner`, a ``Suite.generate``)
plans; :class:`SkillPolicyParams` gives a skill-steering suite's parameters
their shared checks, the policy and the trial's thread limits;
:func:`run_probe` is the command line of a probe of the shipped policy.

>>> from steer_envs.bench.suite import TrialRequest, get_suite
>>> suite = get_suite("itps-blockstack")
>>> request = TrialRequest(envs=suite.envs, methods=("DP-PR",), seeds=(0,), params={"loader": "no_such_module:f"})
>>> plan = plan_with_policy(suite, request, "the BlockStack policy", "train it with a script")
>>> plan.trials, "skipped every method" in plan.notes[0]
((), True)
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from functools import partial
from typing import Any, ClassVar

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Suite, TrialPlan, TrialRequest
from steer_envs.utils.threads import limit_threads

__all__ = ["PRETRAINED_LOADER", "SkillPolicyParams", "plan_with_policy", "policy_planner", "run_probe"]

#: the loader of the shipped checkpoints (:data:`steer_envs.baselines.pretrained.PRETRAINED_LOADER`; spelled out
#: so that declaring a suite imports no torch)
PRETRAINED_LOADER = "steer_envs.baselines.pretrained:load_pretrained"


def plan_with_policy(suite: Suite, request: TrialRequest, what: str, remedy: str) -> TrialPlan:
    """Every env x method x seed of ``request`` whose policy loads; the others skipped with a note.

    A method's policy is the params' ``policy_for(method)`` (or ``policy()``
    for every method), loaded once per ``policy_key(method)`` (methods of one
    key share a policy). ``what`` names the policy in the note (``"the Kitchen
    policy"``), ``remedy`` says how to make it (``"train it with
    scripts/train_kitchen_checkpoint.sh"``). A policy is missing while loading
    it raises one of :data:`~steer_envs.baselines.pretrained.POLICY_UNAVAILABLE`.
    """
    from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE

    params: Any = suite.resolve_params(request.params, request.trials, base=request.base)
    policy_for = getattr(params, "policy_for", lambda method: params.policy())
    key_of = getattr(params, "policy_key", lambda method: None)
    failures: dict[Any, str | None] = {}  # policy key -> why it is missing (None: it loads)
    available: list[str | None] = []
    missing: dict[str, list[str]] = {}
    for method in request.methods:
        key = key_of(method)
        if key not in failures:
            try:
                policy_for(method)
                failures[key] = None
            except POLICY_UNAVAILABLE as exc:
                failures[key] = f"{type(exc).__name__}: {exc}"
        reason = failures[key]
        if reason is None:
            available.append(method)
        else:
            missing.setdefault(reason, []).append(str(method))
    notes = []
    for reason, methods in missing.items():
        which = "every method" if not available else ", ".join(methods)
        note = f"skipped {which}: {what} is not available ({reason}); {remedy} or set --param loader=module:function"
        notes.append(note)
    trials = [
        suite.trial(env, method, seed, params)
        for env in request.envs
        for method in available
        for seed in suite.seed_list(request)
    ]
    return TrialPlan(tuple(trials), tuple(notes))


def policy_planner(what: str, remedy: str) -> Callable[[Suite, TrialRequest], TrialPlan]:
    """A ``Suite.generate`` that plans through :func:`plan_with_policy` with ``what`` and ``remedy``.

    >>> policy_planner("the Kitchen policy", "train it with a script").keywords["what"]
    'the Kitchen policy'
    """
    return partial(plan_with_policy, what=what, remedy=remedy)


class SkillPolicyParams(SuiteParams):
    """Methods of a skill-steering suite's parameters (a frozen dataclass deriving from this one).

    The dataclass declares ``batch`` (plans per steering call),
    ``max_interactions``, ``plot_seeds``, ``torch_threads`` (per trial
    process; 0: torch's default), ``accelerate`` (the denoiser's inference
    mode), ``loader`` (a ``module:function`` returning the policy, called with
    :attr:`policy_name`) and ``checkpoint`` (a checkpoint file that replaces it).
    """

    #: the shipped policy's name (``load_pretrained(policy_name)``)
    policy_name: ClassVar[str]
    batch: int
    max_interactions: int
    plot_seeds: int
    torch_threads: int
    accelerate: str
    loader: str
    checkpoint: str

    def require_steering(self) -> None:
        """The checks of the shared parameters (call from ``__post_init__``)."""
        self.require_between(1, 4096, "batch")
        self.require_between(1, 100, "max_interactions")
        self.require_at_least(0, "plot_seeds")
        self.require("torch_threads", self.torch_threads >= 0, ">= 0 (0: torch's default)")
        from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS  # here: it imports torch

        self.require_in("accelerate", ACCELERATIONS)

    def policy(self) -> Any:
        """The frozen skill policy (cached per process)."""
        from steer_envs.baselines.pretrained import shared_policy

        return shared_policy(self.policy_name, self.checkpoint, self.accelerate, loader=self.loader)

    def policy_for(self, method: str | None) -> Any:
        """The policy ``method`` steers (here: :meth:`policy` for every method; a suite may choose per method)."""
        return self.policy()

    def policy_key(self, method: str | None) -> str:
        """Which policy ``method`` steers, by name: methods of one key share it (here: one for all)."""
        return self.policy_name

    def thread_limits(self) -> AbstractContextManager[None]:
        """A trial's thread limits: one BLAS thread, ``torch_threads`` torch threads."""
        return limit_threads(blas_threads=1, torch_threads=self.torch_threads or None)


def run_probe(
    argv: Sequence[str] | None,
    policy_name: str,
    add_options: Callable[[argparse.ArgumentParser], None],
    probe: Callable[[Any, argparse.Namespace], Any],
    *,
    prog: str,
    description: str,
    errors: tuple[type[Exception], ...] = (TypeError, ValueError),
) -> int:
    """A probe's command line: ``--checkpoint`` (default: the shipped ``policy_name`` policy), its own options,
    ``--threads`` and ``--json``; exit 2 on a usage error.

    ``add_options`` adds the probe's options; ``probe(policy, args)`` runs it, prints its summary and returns
    the JSON-able result that ``--json`` writes. An exception in ``errors`` is a usage error.
    """
    from steer_envs.utils.threads import add_threads_argument, set_process_threads

    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--checkpoint", default="", help="a .safetensors checkpoint (default: the shipped one)")
    add_options(parser)
    add_threads_argument(parser)
    parser.add_argument("--json", default="", help="also write the result as JSON to this file")
    args = parser.parse_args(argv)
    set_process_threads(args.threads)
    from steer_envs.baselines.pretrained import load_pretrained

    try:
        out = probe(load_pretrained(policy_name, checkpoint=args.checkpoint or None), args)
    except errors as err:
        parser.error(str(err))
    if args.json:
        from steer_envs.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(out, indent=2) + "\n")
    return 0
