"""Fuzz pass over the envs' and the core/LTL/users boundaries: random bad values, clean errors only.

Every case calls one public entry point (an env constructor through
``gymnasium.make``, ``reset(seed=..., options=...)``, ``step``, ``perturb``, the
vector envs, Maze2D maps, ``Point``/``Sketch``/``Nudge``, ``TaskSpec``,
``check_steer_env``-style refusals, ``parse``/``translate``/``simplify``, the
replanner, ``from_hoa``, ``SketchUser``) with a random bad value. Each call must
end within a per-case timeout in a documented error (``TypeError``,
``ValueError`` and its subclasses ``LTLParseError``/``FormulaTooDeep``/
``TranslationTooLarge``, ``BoundExceeded``) or in a result; a value that is no
real number (a string, a complex number, NaN/inf, an object, a bool where a
number belongs) in a numeric slot is never accepted. Run with
``pytest -m slow tests/fuzz/test_fuzz_envs.py -s``; it prints the counts.
"""

from __future__ import annotations

import math
import signal
import traceback
from collections import Counter
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.envs.registration import load_env_creator

import steer_envs  # noqa: F401
from steer_envs.core.interaction import Nudge, Point, Sketch
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import BoundExceeded
from steer_envs.envs.maze2d import Maze2DEnv
from steer_envs.envs.maze_grid import MazeGrid
from steer_envs.envs.registry import entry, env_ids
from steer_envs.envs.soup_scoop import SOUP_TASK
from steer_envs.ltl import Atom, ModeReplanner, Next, Xor, from_hoa, parse, simplify, specs, to_hoa, translate
from steer_envs.users.sketcher import SketchUser

pytestmark = pytest.mark.slow

CASES = 3000
PER_CASE_S = 20.0
DOCUMENTED = (TypeError, ValueError, BoundExceeded)


class _Hang(BaseException):
    """Raised by SIGALRM: the case ran past its timeout."""


def _alarm(*_: object) -> None:
    raise _Hang


def _not_real(rng: np.random.Generator, dim: int = 2) -> Any:
    """A value that must be refused in any numeric slot."""
    good = rng.uniform(-5, 5, dim)
    table: list[Any] = [
        str(float(good[0])),
        [str(v) for v in good],
        complex(good[0], 1.0),
        good + 1j,
        [complex(v) for v in good],
        math.nan,
        math.inf,
        [*good[:-1], math.nan],
        [*good[:-1], -math.inf],
        np.float32("nan"),
        object(),
        b"\x00\x01",
        {"x": 1},
        {1.0, 2.0},
        np.array(list(good), dtype=object),
        [bool(v > 0) for v in good],
        np.array([v > 0 for v in good]),
        torch.tensor(good + 1j),
        "no",
        "",
        [None] * dim,
        [[1.0, 2.0], [3.0]],
    ]
    return table[int(rng.integers(len(table)))]


def _odd(rng: np.random.Generator, dim: int = 2) -> Any:
    """A value of the right kind but often of a wrong shape or range (may be accepted)."""
    good = rng.uniform(-5, 5, dim)
    table: list[Any] = [
        None,
        int(rng.integers(-(10**12), 10**12)),
        float(rng.uniform(-1e9, 1e9)),
        -1,
        0,
        10**30,
        1e308,
        list(good),
        rng.uniform(-1e300, 1e300, dim),
        rng.uniform(-5, 5, int(rng.integers(0, 5))),
        np.array([list(good), list(good)]),
        torch.tensor(good, requires_grad=True),
        np.float32(good[0]),
        np.int64(3),
    ]
    return table[int(rng.integers(len(table)))]


def _value(rng: np.random.Generator, dim: int = 2) -> tuple[Any, bool]:
    if rng.random() < 0.65:
        return _not_real(rng, dim), True
    return _odd(rng, dim), False


# ---------------------------------------------------------------- the boundaries
_ENVS: dict[str, Any] = {}


def _env(env_id: str) -> Any:
    if env_id not in _ENVS:
        _ENVS[env_id] = gym.make(env_id).unwrapped
    env = _ENVS[env_id]
    env.reset(seed=0)
    return env


#: the envs this pass makes: the robosuite arms are left out (one costs seconds to build and their
#: boundaries have example tests in tests/envs/test_robosuite.py)
FUZZ_ENV_IDS = [e for e in env_ids() if not entry(e).entry_point.startswith("steer_envs.envs.robosuite")]

_KWARGS = {
    "SoupScoop": ("dt", "max_speed", "sensor_convention", "render_size", "render_mode"),
    "ConvexMode": ("layout_seed", "start_noise", "terminate_on_violation", "dt", "max_speed", "render_size"),
    "Cooking": ("dt", "max_speed", "render_size"),
    "PolygonNav": ("layout_seed", "terminate_on_violation", "workspace_margin", "min_gap", "render_size"),
    "Maze2D": ("frame_skip", "observe_velocity", "sample_goal", "cell_px", "relative_actions", "render_mode"),
}


def _case_make(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    env_id = str(rng.choice(FUZZ_ENV_IDS))
    family = next(k for k in _KWARGS if k in env_id)
    name = str(rng.choice(_KWARGS[family]))
    value, must_refuse = _value(rng, 1)

    def call() -> Any:
        if name == "render_mode":  # gym.make reads render_mode itself first (str methods): build the class directly
            spec = gym.spec(env_id)
            env = load_env_creator(spec.entry_point)(**spec.kwargs, render_mode=value)
        else:
            env = gym.make(env_id, **{name: value})
        env.close()

    # None is a valid start_noise / render_mode; a 0-d numeric value may be a valid float argument
    return f"make({env_id}, {name})", call, must_refuse


def _case_step(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    env = _env(str(rng.choice(FUZZ_ENV_IDS)))
    value, must_refuse = _value(rng)
    return f"step({type(env).__name__})", lambda: env.step(value), must_refuse


def _case_perturb(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    env = _env(str(rng.choice(FUZZ_ENV_IDS)))
    value, must_refuse = _value(rng)
    key = "delta" if rng.random() < 0.5 else "to"
    return f"perturb({type(env).__name__}, {key})", lambda: env.perturb(**{key: value}), must_refuse


def _case_reset(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    env = _env(str(rng.choice(FUZZ_ENV_IDS)))
    value, must_refuse = _value(rng)
    which = int(rng.integers(4))
    if which == 0:
        return "reset(seed)", lambda: env.reset(seed=value), must_refuse or isinstance(value, float)
    if which == 1:
        return "reset(options[state])", lambda: env.reset(options={"state": value}), must_refuse and value is not None
    if which == 2:
        return "reset(options)", lambda: env.reset(options=value), must_refuse
    key = str(rng.choice(["goal_cell", "start", "State", ""]))
    return f"reset(options[{key!r}])", lambda: env.reset(options={key: value}), key != "goal_cell" or must_refuse


def _case_vector(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    env_id = str(rng.choice(env_ids(kinematic_only=True)))
    key = f"vec:{env_id}"
    if key not in _ENVS:
        _ENVS[key] = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv = _ENVS[key]
    venv.reset(seed=0)
    value, must_refuse = _value(rng, 6)
    arr = value
    if isinstance(value, np.ndarray) and value.size == 6:
        arr = value.reshape(3, 2)
    which = int(rng.integers(3))
    if which == 0:
        return "vector.step", lambda: venv.step(arr), must_refuse
    if which == 1:
        bad_masks: list[Any] = [[1, 0, 1], ["no"] * 3, [1.0, 0.0, 1.0], "yes", [None] * 3, np.ones(3), [True, False]]
        mask, mask_bad = (
            (bad_masks[int(rng.integers(len(bad_masks)))], True)
            if rng.random() < 0.5
            else (np.array([True, False, True]), False)
        )
        return "vector.perturb", lambda: venv.unwrapped.perturb(arr, mask), must_refuse or mask_bad
    return "vector.reset(state)", lambda: venv.reset(options={"state": arr}), must_refuse and value is not None


def _case_maze_map(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    rows, cols = int(rng.integers(1, 6)), int(rng.integers(1, 6))
    cells: list[list[Any]] = [[int(rng.integers(2)) for _ in range(cols)] for _ in range(rows)]
    bad = [
        "1",
        "0",
        True,
        1.0,
        2,
        -1,
        None,
        "x",
        [1],
        np.float64(0.0),
        1 + 0j,
    ][int(rng.integers(11))]
    cells[int(rng.integers(rows))][int(rng.integers(cols))] = bad
    if rng.random() < 0.5:
        return "MazeGrid(map)", lambda: MazeGrid(cells), True
    return "Maze2DEnv(map)", lambda: Maze2DEnv(cells), True


def _case_interaction(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    cls = [Point, Sketch, Nudge][int(rng.integers(3))]
    value, must_refuse = _value(rng, 2)
    if cls is not Point and rng.random() < 0.5:
        value = [value, value]
    return f"{cls.__name__}()", lambda: cls(value), must_refuse


def _case_task(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    value, _ = _value(rng, 1)
    if rng.random() < 0.5:
        return "TaskSpec.mode_of", lambda: SOUP_TASK.mode_of({"r": value, "s": False, "t": False}), True
    field = str(rng.choice(["name", "modes", "sensors", "goal", "transitions", "sensor_modes"]))
    kwargs: dict[str, Any] = {"name": "t", "modes": ("a", "b")}
    kwargs[field] = value
    default = field in ("goal", "transitions", "sensors", "sensor_modes") and value is None  # None: the default
    names = isinstance(value, list) and all(isinstance(v, str) and v for v in value)  # e.g. ['1.5', '-2.0']
    valid = default or (field == "name" and isinstance(value, str)) or (field in ("modes", "sensors") and names)
    return f"TaskSpec({field})", lambda: TaskSpec(**kwargs), not valid


_REPLANNER: list[ModeReplanner] = []


def _case_ltl(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    which = int(rng.integers(6))
    if which == 0:  # random operator soup, possibly very deep
        alphabet = [*'()!&|^~<>-=XFGURWMV abtp01"\\', " xor ", " -> ", "(((", ")))"]
        n = int(rng.integers(1, 4000))
        text = "".join(alphabet[int(k)] for k in rng.integers(len(alphabet), size=n))
        return "parse(random)", lambda: parse(text), False
    if which == 1:  # deep nesting of one operator
        depth = int(rng.integers(100, 3000))
        op = ["X ", "F ", "G ", "!"][int(rng.integers(4))]
        text = op * depth + "a" if rng.random() < 0.5 else "(" * depth + "a" + ")" * depth
        fn = [parse, translate, simplify][int(rng.integers(3))]
        return f"{fn.__name__}(deep)", lambda: fn(text), False
    if which == 2:
        f: Any = Atom("a")
        for i in range(int(rng.integers(100, 2000))):
            f = Xor(f, Atom(f"b{i % 3}")) if rng.random() < 0.5 else Next(f)
        fn2 = [str, translate, simplify][int(rng.integers(3))]
        return f"{getattr(fn2, '__name__', 'str')}(built)", lambda: fn2(f), False
    if which == 3:
        if not _REPLANNER:
            _REPLANNER.append(ModeReplanner(SOUP_TASK, specs.soup_scoop("public")))
        replanner = _REPLANNER[0]
        value, _ = _value(rng, 1)
        reading = {"r": False, "s": value, "t": False}
        return (
            "replanner.update",
            lambda: (replanner.reset({"r": False, "s": False, "t": False}), replanner.update(reading)),
            True,
        )
    if which == 4:
        good = to_hoa(translate("G(a -> F b)"))
        cut, at = int(rng.integers(len(good))), int(rng.integers(len(good)))
        junk = "".join(chr(int(c)) for c in rng.integers(32, 127, size=int(rng.integers(1, 6))))
        text = good[:cut] if rng.random() < 0.5 else good[:at] + junk + good[at:]
        return "from_hoa", lambda: from_hoa(text), False
    value, must_refuse = _value(rng, 1)
    key = str(rng.choice(["aps", "simplify_formula", "backend"]))
    return f"translate({key})", lambda: translate("a U b", **{key: value}), key != "aps" or must_refuse


def _case_sketcher(rng: np.random.Generator) -> tuple[str, Callable[[], Any], bool]:
    value, must_refuse = _value(rng, 1)
    if rng.random() < 0.5:
        name = str(rng.choice(["through_wall", "min_length", "max_length", "points", "hand_jitter", "seed"]))
        return f"SketchUser({name})", lambda: SketchUser("umaze", **{name: value}), must_refuse and value is not None
    user = SketchUser("umaze", seed=0, points=8, min_length=2.0, max_length=4.0)
    start, bad = _value(rng, 2)
    return "SketchUser.draw", lambda: user.draw(start), bad


CASE_MAKERS = [
    _case_make,
    _case_step,
    _case_perturb,
    _case_reset,
    _case_vector,
    _case_maze_map,
    _case_interaction,
    _case_task,
    _case_ltl,
    _case_sketcher,
]


def test_fuzz_env_core_ltl_boundaries() -> None:
    rng = np.random.default_rng(15)
    outcomes: Counter[str] = Counter()
    accepted_bad: list[str] = []
    tracebacks: list[str] = []
    hangs: list[str] = []
    previous = signal.signal(signal.SIGALRM, _alarm)
    try:
        for i in range(CASES):
            maker = CASE_MAKERS[i % len(CASE_MAKERS)]
            label, call, must_refuse = maker(rng)
            signal.setitimer(signal.ITIMER_REAL, PER_CASE_S)
            try:
                call()
            except _Hang:
                hangs.append(label)
                outcomes["hang"] += 1
            except DOCUMENTED as err:
                outcomes[type(err).__name__] += 1
            except Exception as err:  # the point of the fuzz pass: anything else is a finding
                tracebacks.append(f"{label}: {type(err).__name__}: {err}\n{traceback.format_exc(limit=4)}")
                outcomes["other"] += 1
            else:
                outcomes["accepted"] += 1
                if must_refuse:
                    accepted_bad.append(label)
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
    finally:
        signal.signal(signal.SIGALRM, previous)
        for env in _ENVS.values():
            env.close()
    print(f"\nfuzz envs/core/ltl/users: {CASES} cases: {dict(sorted(outcomes.items()))}")
    assert not hangs, hangs
    assert not tracebacks, "\n".join(tracebacks[:5])
    assert not accepted_bad, accepted_bad[:10]
