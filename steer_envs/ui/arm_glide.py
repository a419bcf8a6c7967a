"""GLiDE on a robosuite arm in steer-ui: GLiDE+BC acts on the modes its classifier learned; the page shows them.

:class:`GlideArmController` runs GLiDE+BC
(:func:`~steer_envs.baselines.glide.arm_policies.train_arm_policy`) on Lift: at
every step the mode classifier (trained from success labels alone on the
expert's demos and their perturbed replays,
:func:`~steer_envs.baselines.glide.arm_grounding.train_arm_predictor`) names
the mode, and that mode's BC (pulled toward the mode's pseudo-attractor far
from it) acts. Drawn: the gripper's path since the reset, the current learned
mode's attractor, and a strip of the learned mode beside the true one along
the run; a drag of the gripper is a push (``perturb``).

What it trains is set by :class:`ArmGlideSetup`: the replay data are built
into ``cache_dir`` shard by shard, and the classifier is kept there
(safetensors), so only the first start trains it; the BC networks are
trained at each start (seconds).

>>> ArmGlideSetup().task, quick_arm_glide_setup().n_demos
('lift', 4)
"""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, one_of
from steer_envs.ui.controllers import DEFAULT_CACHE_DIR, Controller, PushView, _cached, _round

__all__ = ["ArmGlideSetup", "GlideArmController", "mode_runs", "quick_arm_glide_setup"]

#: steps of the run the mode strip shows (the latest ones)
STRIP_STEPS = 400


@dataclass(frozen=True)
class ArmGlideSetup:
    """The data and training of the arm's GLiDE: demos (the first ``replay_demos`` with perturbed replays),
    the classifier's epochs and heads, and the size and steps of each mode's BC network."""

    task: str = "lift"
    n_demos: int = 20
    replay_demos: int = 10
    replays_per_demo: int = 10
    epochs: int = 1000
    n_heads: int = 5
    bc_hidden: tuple[int, ...] = (128, 128)
    bc_steps: int = 1500
    seed: int = 0

    def __post_init__(self) -> None:
        owner = "ArmGlideSetup"
        one_of(self.task, "task", ("lift", "can"), owner=owner)
        integer(self.n_demos, "n_demos", low=1, high=1000, owner=owner)
        integer(self.replay_demos, "replay_demos", low=1, high=self.n_demos, owner=owner)
        integer(self.replays_per_demo, "replays_per_demo", low=1, high=100, owner=owner)
        integer(self.epochs, "epochs", low=1, owner=owner)
        integer(self.n_heads, "n_heads", low=1, high=16, owner=owner)
        integer(self.bc_steps, "bc_steps", low=1, owner=owner)
        integer(self.seed, "seed", low=0, owner=owner)

    def key(self) -> str:
        """A short hash of the fields the classifier depends on (its cache file's name)."""
        fields = {k: v for k, v in asdict(self).items() if not k.startswith("bc_")}
        return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:10]


def quick_arm_glide_setup() -> ArmGlideSetup:
    """A small setup for tests: 4 demos (2 with 4 replays), 150 epochs, 2 heads, small BC (about 20 s).

    Its learned modes agree with the true ones far less often than the default's (the page still shows both).
    """
    return ArmGlideSetup(
        n_demos=4, replay_demos=2, replays_per_demo=4, epochs=150, n_heads=2, bc_hidden=(64, 64), bc_steps=300
    )


def _train(setup: ArmGlideSetup, cache: Path) -> tuple[Any, Any]:
    """(the mode predictor, GLiDE+BC) of ``setup``; the data and the classifier cached under ``cache``."""
    from steer_envs.baselines.glide import ArmBCSettings, ArmGroundingSetup, train_arm_policy, train_arm_predictor
    from steer_envs.baselines.glide.classifier import ModeClassifier
    from steer_envs.data.robosuite_replay_sets import split_demos
    from steer_envs.data.robosuite_shards import ShardSettings, read_shards
    from steer_envs.io import CheckpointError

    shards = [
        ShardSettings(setup.task, i, replay_demos=setup.replay_demos, replays_per_demo=setup.replays_per_demo)
        for i in range(setup.n_demos)
    ]
    trajectories = read_shards(cache / "shards", shards)
    path = cache / f"{setup.task}-classifier-{setup.key()}.safetensors"
    predictor: Any = None
    if path.exists():
        try:
            predictor = ModeClassifier.load(path)
        except CheckpointError as err:  # a corrupt cache entry is a miss: retrain and overwrite it
            warnings.warn(f"retraining the cached classifier: {err}", RuntimeWarning, stacklevel=2)
    if predictor is None:
        grounding = ArmGroundingSetup(
            n_demos=setup.n_demos,
            replay_demos=setup.replay_demos,
            replays_per_demo=setup.replays_per_demo,
            epochs=setup.epochs,
            n_heads=setup.n_heads,
            prune_to=min(2, setup.n_heads),
        )
        predictor, _ = train_arm_predictor(setup.task, "full", trajectories, seed=setup.seed, setup=grounding)
        path.parent.mkdir(parents=True, exist_ok=True)
        predictor.save(path, extra={"setup": asdict(setup)})
    demos, _ = split_demos(trajectories)
    bc = ArmBCSettings(hidden=tuple(setup.bc_hidden), steps=setup.bc_steps)
    policy = train_arm_policy(setup.task, "glide_bc", setup.seed, demos=demos, predictor=predictor, bc=bc)
    return predictor, policy


def mode_runs(modes: list[int], names: tuple[str, ...], last: int = 6) -> str:
    """A run of modes as ``name ×count`` pieces (the ``last`` ones).

    >>> mode_runs([0, 0, 1, 1, 1, 0], ("reach", "lift"))
    'reach ×2 → lift ×3 → reach ×1'
    >>> mode_runs([0, 1, 0, 1], ("reach", "lift"), last=2)
    '… → reach ×1 → lift ×1'
    """
    pieces: list[str] = []
    start = 0
    for i in range(1, len(modes) + 1):
        if i == len(modes) or modes[i] != modes[start]:
            k = modes[start]
            pieces.append(f"{names[k] if 0 <= k < len(names) else k} ×{i - start}")
            start = i
    if len(pieces) > last:
        pieces = ["…", *pieces[-last:]]
    return " → ".join(pieces) or "–"


class GlideArmController(Controller):
    """GLiDE+BC on a robosuite arm (Lift) over the modes its classifier learned; see the module.

    ``setup``: :class:`ArmGlideSetup` (default: its defaults, about 3 minutes on one core the first time);
    ``cache_dir``: where the data and the classifier are kept.
    """

    def __init__(self, env: Any, setup: ArmGlideSetup | None = None, cache_dir: str | Path | None = None) -> None:
        from steer_envs.baselines.glide import selected_columns

        self.base = env.unwrapped
        self.setup = setup or ArmGlideSetup()
        if not isinstance(self.setup, ArmGlideSetup):
            raise TypeError(f"GlideArmController: `setup` must be an ArmGlideSetup, got {type(setup).__name__}")
        task = str(getattr(self.base, "task_name", ""))
        if task != self.setup.task:
            raise ValueError(f"GlideArmController: the env's task is {task!r}, the setup's {self.setup.task!r}")
        cache = Path(cache_dir) if cache_dir is not None else DEFAULT_CACHE_DIR / "glide-arm"
        self.predictor, self.policy = _cached(("glide-arm", self.setup, str(cache)), lambda: _train(self.setup, cache))
        self.columns = selected_columns(self.setup.task)
        self.mode_names: tuple[str, ...] = tuple(self.base.task.modes)
        limit = getattr(getattr(self.base, "spec", None), "max_episode_steps", None)
        #: the steps the mode strip spans (an episode's, at most :data:`STRIP_STEPS`)
        self.strip_steps = min(STRIP_STEPS, int(limit) + 1) if limit else STRIP_STEPS
        self.learned: list[int] = []
        self.true: list[int] = []
        self.trail: list[np.ndarray] = []
        self.mode = 0
        self._features = np.zeros(0, dtype=np.float32)
        self._fresh = False

    def _read(self, info: dict[str, Any]) -> None:
        """The learned mode of the current state, logged beside the true one (the latest :data:`STRIP_STEPS`)."""
        from steer_envs.data import robosuite_replays as rr

        self._features = rr.feature_vector(self.base)
        chosen = np.asarray(self._features[self.columns], dtype=np.float64)[None]
        self.mode = int(self.predictor.predict(chosen)[0])
        self.learned.append(self.mode)
        self.true.append(int(info.get("mode", -1)))
        self.trail.append(np.asarray(self.base.state, dtype=np.float64))
        del self.learned[:-STRIP_STEPS], self.true[:-STRIP_STEPS], self.trail[:-STRIP_STEPS]
        self._fresh = True

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.learned, self.true, self.trail = [], [], []
        self._read(info)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        if not self._fresh:  # the state of the last step's result: read it (a reset or push already did)
            self._read(info)
        self._fresh = False
        return np.asarray(self.policy.act(np.asarray(obs), self._features, self.mode), dtype=np.float32)

    def observe(self, obs: Any, info: dict[str, Any]) -> None:
        self._read(info)

    def agent(self, base: Any) -> np.ndarray:
        """The gripper's position (m)."""
        return np.asarray(base.state, dtype=np.float64)

    def overlays(self, view: PushView, state: np.ndarray, full: bool) -> dict[str, Any]:
        attractors = getattr(self.policy, "attractors", None)
        target: list[Any] = []
        if attractors is not None and 0 <= self.mode < len(attractors) and len(self._features):
            target = _round(view.to_pixels(np.asarray(attractors[self.mode].target(self._features))[None]))
        trail = [_round(view.to_pixels(np.asarray(self.trail)))] if len(self.trail) > 1 else []
        strip = {"rows": [["learned", list(self.learned)], ["true", list(self.true)]], "steps": self.strip_steps}
        return {"trail": trail, "target": target, "modes": strip}

    def panel(self, state: np.ndarray, info: dict[str, Any]) -> list[tuple[str, str]]:
        """The learned mode beside the true one, now and along the run (the state after the last step read first)."""
        if not self._fresh:
            self._read(info)
        names = self.mode_names
        learned = names[self.mode] if 0 <= self.mode < len(names) else str(self.mode)
        true = str(info.get("mode_name", "–"))
        agree = float(np.mean(np.asarray(self.learned) == np.asarray(self.true))) if self.learned else 0.0
        return [
            ("learned mode", learned),
            ("true mode", true),
            ("agree", "yes" if learned == true else "no"),
            ("agreement along the run", f"{agree:.0%} of {len(self.learned)} steps"),
            ("learned along the run", mode_runs(self.learned, names)),
            ("true along the run", mode_runs(self.true, names)),
        ]
