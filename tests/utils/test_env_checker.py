"""check_steer_env: a toy env that follows the contract passes; one broken copy per convention fails, by name."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from steer_envs.core.env import PerturbableEnv, SteerEnv, perturbable_env, steer_env, task_of
from steer_envs.core.task import TaskSpec
from steer_envs.utils import CONVENTIONS, SteerEnvCheckError, check_steer_env

TASK = TaskSpec(
    name="toy",
    modes=("left", "right"),
    sensors=("r",),
    sensor_modes={frozenset(): "left", frozenset({"r"}): "right"},
    transitions=frozenset({("left", "right")}),
)


class ToyEnv(gym.Env[np.ndarray, np.ndarray]):
    """A point in [-1, 1]^2 moved by its velocity action; mode "right" (the goal) once x >= 0."""

    interaction_kinds: tuple[str, ...] = ("point", "sketch")
    task = TASK

    def __init__(self) -> None:
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.action_space = spaces.Box(-0.1, 0.1, shape=(2,), dtype=np.float32)
        self._pos = np.zeros(2)

    @property
    def state(self) -> np.ndarray:
        return self._pos.copy()

    def _mode(self) -> int:
        return int(self._pos[0] >= 0.0)

    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        mode = self._mode()
        return {
            "mode": mode,
            "mode_name": TASK.modes[mode],
            "sensors": {"r": mode == 1},
            "success": mode == 1,
            "is_success": mode == 1,
            "constraint_violation": False,
            "perturbed": perturbed,
        }

    def _check(self, value: Any, name: str) -> np.ndarray:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError(f"{name} must be 2 floats, got {type(value).__name__}") from None
        if arr.shape != (2,) or not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be 2 finite floats, got shape {arr.shape}")
        return arr

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self._pos = self.np_random.uniform([-1.0, -1.0], [-0.5, 1.0])
        return self._pos.astype(np.float32), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._pos = np.clip(self._pos + self._check(action, "action"), -1.0, 1.0)
        info = self._info()
        return self._pos.astype(np.float32), float(info["success"]), info["success"], False, info

    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        if (delta is None) == (to is None):
            raise ValueError("perturb: pass exactly one of `delta` or `to`")
        target = self._pos + self._check(delta, "delta") if to is None else self._check(to, "to")
        self._pos = np.clip(target, -1.0, 1.0)
        return self._info(perturbed=True)


# ----------------------------------------------------------- one broken env per convention
class NoPerturb(ToyEnv):
    perturb = None  # type: ignore[assignment]


class NoTask(ToyEnv):
    task = ("left", "right")  # type: ignore[assignment]


class UnknownKind(ToyEnv):
    interaction_kinds = ("point", "wave")


class ObsOutsideSpace(ToyEnv):
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        obs, info = super().reset(seed=seed, options=options)
        return obs.astype(np.float64) * 10.0, info


class NoViolationKey(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        del info["constraint_violation"]
        return info


class NumpyMode(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        return {**super()._info(perturbed), "mode": np.int64(self._mode())}


class WrongModeName(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        return {**super()._info(perturbed), "mode_name": "middle"}


class ExtraSensor(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        return {**info, "sensors": {**info["sensors"], "extra": False}}


class InvertedSensor(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        return {**info, "sensors": {"r": not info["sensors"]["r"]}}


class NumpySuccess(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        return {**info, "success": np.bool_(info["success"])}


class NoIsSuccess(ToyEnv):
    """Only the steer-envs name: stable-baselines3's Monitor would never see a success."""

    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        del info["is_success"]
        return info


class IsSuccessDiffers(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        return {**info, "is_success": not info["success"]}


class IsSuccessNumpy(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        info = super()._info(perturbed)
        return {**info, "is_success": np.bool_(info["success"])}


class AlwaysPerturbed(ToyEnv):
    def _info(self, perturbed: bool = False) -> dict[str, Any]:
        return super()._info(True)


class UnseededReset(ToyEnv):
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self._pos = np.random.default_rng().uniform([-1.0, -1.0], [-0.5, 1.0])
        return self._pos.astype(np.float32), self._info()


class SharedState(ToyEnv):
    @property
    def state(self) -> np.ndarray:
        return self._pos


class PerturbNotFlagged(ToyEnv):
    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        return {**super().perturb(delta, to=to), "perturbed": False}


class PerturbIgnoresTo(ToyEnv):
    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        if to is not None:
            to = 0.5 * (self._check(to, "to") + self._pos)
        return super().perturb(delta, to=to)


class PerturbDeltaTwice(ToyEnv):
    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        return super().perturb(None if delta is None else 2.0 * self._check(delta, "delta"), to=to)


class PerturbTakesBoth(ToyEnv):
    def perturb(self, delta: Any = None, *, to: Any = None) -> dict[str, Any]:
        return super().perturb(delta) if delta is not None else super().perturb(to=to)


class PerturbAcceptsNaN(ToyEnv):
    def _check(self, value: Any, name: str) -> np.ndarray:
        return (
            np.nan_to_num(np.resize(np.asarray(value, dtype=np.float64), 2))
            if name == "delta"
            else super()._check(value, name)
        )


class PerturbVagueError(ToyEnv):
    def _check(self, value: Any, name: str) -> np.ndarray:
        try:
            return super()._check(value, name)
        except ValueError:
            raise ValueError("bad input") from None


class ActionResized(ToyEnv):
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return super().step(np.resize(np.asarray(action), 2))


class ActionFromWords(ToyEnv):
    """Reads any string as a small number: the silent coercion a non-numeric action must not get."""

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        arr = np.asarray(action)
        if arr.dtype.kind == "U":
            action = np.array([0.01 * len(str(v)) for v in arr.ravel()])
        return super().step(action)


class ActionWordsCrash(ToyEnv):
    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if np.asarray(action).dtype.kind == "U":
            raise IndexError("deep inside")
        return super().step(action)


BROKEN: list[tuple[type[ToyEnv], str, str]] = [
    (NoPerturb, "members", "perturb"),
    (NoTask, "members", "TaskSpec"),
    (UnknownKind, "interaction_kinds", "wave"),
    (ObsOutsideSpace, "gymnasium_api", "observation"),
    (NoViolationKey, "info_keys", "constraint_violation"),
    (NumpyMode, "mode", "int64"),
    (WrongModeName, "mode", "middle"),
    (ExtraSensor, "sensors", "extra"),
    (InvertedSensor, "sensor_labelling", "label"),
    (NumpySuccess, "flags", "success"),
    (AlwaysPerturbed, "flags", "perturbed"),
    (NoIsSuccess, "info_keys", "is_success"),
    (IsSuccessDiffers, "is_success", "info\\['is_success'\\] = True .*info\\['success'\\] = False"),
    (IsSuccessNumpy, "is_success", "bool_"),
    (UnseededReset, "determinism", "seed 0"),
    (SharedState, "state", "copy"),
    (PerturbNotFlagged, "perturb", "perturbed"),
    (PerturbIgnoresTo, "perturb", "left the agent"),
    (PerturbDeltaTwice, "perturb", "state \\+ delta"),
    (PerturbTakesBoth, "perturb_arguments", "raised no ValueError"),
    (PerturbAcceptsNaN, "perturb_arguments", "nan"),
    (PerturbVagueError, "perturb_arguments", "does not name `delta`"),
    (ActionResized, "action_arguments", "accepted an action"),
    (ActionFromWords, "action_arguments", "was accepted as an action"),
    (ActionWordsCrash, "action_arguments", "IndexError"),
]


def test_the_toy_env_follows_the_contract() -> None:
    env = ToyEnv()
    check_steer_env(env)
    assert isinstance(env, SteerEnv) and isinstance(env, PerturbableEnv)
    assert steer_env(env) is env and perturbable_env(env) is env and task_of(env) is TASK


@pytest.mark.filterwarnings("ignore::UserWarning")  # Gymnasium's checker warns about some of the broken envs
@pytest.mark.parametrize(("cls", "convention", "detail"), BROKEN, ids=[b[0].__name__ for b in BROKEN])
def test_each_broken_convention_is_named(cls: type[ToyEnv], convention: str, detail: str) -> None:
    with pytest.raises(SteerEnvCheckError, match=detail) as caught:
        # Gymnasium's own checker would catch a reset that ignores its seed first
        check_steer_env(cls(), gymnasium_checks=convention != "determinism")
    assert caught.value.convention == convention
    assert caught.value.env == cls.__name__
    assert str(caught.value).startswith(f"{cls.__name__} breaks the steer-env convention {convention!r}")


def test_every_convention_has_a_broken_env() -> None:
    assert {convention for _, convention, _ in BROKEN} == set(CONVENTIONS)


def test_a_wrapped_registered_env_is_checked_through_its_wrappers() -> None:
    import steer_envs  # noqa: F401  (registers the ids)

    env = gym.wrappers.RecordEpisodeStatistics(gym.make("steer_envs/PolygonNav-3Mode-v0"))
    check_steer_env(env, seed=3, steps=5)
    assert task_of(env).num_modes == 3


def test_bad_arguments() -> None:
    with pytest.raises(TypeError, match=r"gymnasium\.Env"):
        check_steer_env("ToyEnv")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="steps"):
        check_steer_env(ToyEnv(), steps=0)
    with pytest.raises(TypeError, match="seed"):
        check_steer_env(ToyEnv(), seed="0")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"_Bare \(_Bare\) lacks `task`, `state`, `perturb`, `interaction_kinds`"):
        steer_env(_Bare())


class _Bare(gym.Env[np.ndarray, np.ndarray]):
    observation_space = spaces.Box(-1.0, 1.0, shape=(2,))
    action_space = spaces.Box(-1.0, 1.0, shape=(2,))
