"""Fuzz pass over the file boundaries: checkpoints, datasets, training records, policy inputs, writers.

Random damage and random values go to every loader and to the policies' inputs.
Each case must end, within a per-case timeout, in a result or in its documented
error: :class:`~steer_envs.io.CheckpointError` for checkpoint and record files,
:class:`~steer_envs.io.DatasetError` for dataset files, ``TypeError`` /
``ValueError`` for bad arguments. A loaded policy must hold finite weights.
Writers killed mid-write must leave the old file. Run with
``pytest -m slow tests/fuzz/test_fuzz_files.py -s``; it prints the counts.
"""

from __future__ import annotations

import io
import json
import multiprocessing
import os
import signal
import struct
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from samples import tiny_counterfactual

from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.bc import BCConfig, BCPolicy
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.factory import load_policy
from steer_envs.baselines.glide.classifier import ModeClassifier
from steer_envs.baselines.training import read_record
from steer_envs.data.counterfactual_dataset import CounterfactualDataset
from steer_envs.data.maze_random_walk import generate_random_walk, load_random_walk, save_random_walk
from steer_envs.data.trajectories import TrajectoryDataset, load_trajectories, save_trajectories
from steer_envs.io import CheckpointError, DatasetError, atomic_write_bytes

pytestmark = pytest.mark.slow

CASES = 1500
PER_CASE_S = 10.0
KILLS = 20


class _Hang(BaseException):
    """Raised by SIGALRM: the case ran past its timeout."""


def _alarm(*_: object) -> None:
    raise _Hang


# ------------------------------------------------------------------------ fixtures
def _dp() -> DiffusionPolicy:
    cfg = DiffusionConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16), obs_embed_dim=8, step_embed_dim=8)
    return DiffusionPolicy(cfg)


def _act() -> ACTPolicy:
    return ACTPolicy(ACTConfig(obs_dim=2, action_dim=2, chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8))


def _files(folder: Path) -> dict[str, tuple[bytes, Callable[[Path], Any], type[Exception]]]:
    """kind -> (good bytes, loader, the loader's error type)."""
    out: dict[str, tuple[bytes, Callable[[Path], Any], type[Exception]]] = {}
    out["dp"] = (_dp().save(folder / "dp.safetensors").read_bytes(), load_policy, CheckpointError)
    out["act"] = (_act().save(folder / "act.safetensors").read_bytes(), load_policy, CheckpointError)
    bc = BCPolicy(BCConfig(hidden=(8,), epochs=1, standardize=True))
    bc.fit(np.random.default_rng(0).uniform(-1, 1, (16, 2)), np.zeros((16, 2)))
    out["bc"] = (bc.save(folder / "bc.safetensors").read_bytes(), BCPolicy.load, CheckpointError)
    clf = ModeClassifier(2, 3, hidden=4, n_heads=2).save(folder / "clf.safetensors")
    out["clf"] = (clf.read_bytes(), ModeClassifier.load, CheckpointError)
    traj = TrajectoryDataset(np.random.default_rng(0).normal(size=(20, 2)), np.zeros((20, 2)), meta={"s": 1})
    out["traj"] = (save_trajectories(traj, folder / "t.npz").read_bytes(), load_trajectories, DatasetError)
    walk = save_random_walk(generate_random_walk("umaze", 80, seed=0, progress=False), folder / "w.npz")
    out["walk"] = (walk.read_bytes(), load_random_walk, DatasetError)
    cf = tiny_counterfactual().save(folder / "c.npz")
    out["cf"] = (cf.read_bytes(), CounterfactualDataset.load, DatasetError)
    return out


# --------------------------------------------------------------------------- damage
def _damage(rng: np.random.Generator, raw: bytes) -> bytes:
    data = bytearray(raw)
    how = int(rng.integers(5))
    if how == 0:  # truncate
        return bytes(data[: int(rng.integers(0, len(data)))])
    if how == 1:  # flip bytes anywhere
        for _ in range(int(rng.integers(1, 8))):
            data[int(rng.integers(len(data)))] ^= int(rng.integers(1, 256))
        return bytes(data)
    if how == 2:  # flip bytes in the first kB (headers)
        for _ in range(int(rng.integers(1, 4))):
            data[int(rng.integers(min(1024, len(data))))] ^= int(rng.integers(1, 256))
        return bytes(data)
    if how == 3:  # append junk
        return bytes(data) + rng.bytes(int(rng.integers(1, 200)))
    return rng.bytes(int(rng.integers(0, 400)))  # noise


_JSON_VALUES: list[Any] = [
    None,
    True,
    -1,
    0,
    2**40,
    1.5,
    float("nan"),
    "x",
    "64",
    [],
    [65536] * 3,
    [1, "a"],
    {},
    {"a": [1, {"b": None}]},
    [[[[[]]]]],
]


def _mutate_header(rng: np.random.Generator, raw: bytes, meta_key: str) -> bytes:
    """Replace one field of the JSON metadata (at the top or in ``config``) with a random JSON value."""
    n = int.from_bytes(raw[:8], "little")
    header = json.loads(raw[8 : 8 + n])
    meta = json.loads(header["__metadata__"][meta_key])
    target = meta["config"] if isinstance(meta.get("config"), dict) and rng.random() < 0.7 else meta
    keys = [*sorted(target), "unknown"]
    target[keys[int(rng.integers(len(keys)))]] = _JSON_VALUES[int(rng.integers(len(_JSON_VALUES)))]
    header["__metadata__"][meta_key] = json.dumps(meta)
    text = json.dumps(header).encode()
    return struct.pack("<Q", len(text)) + text + raw[8 + n :]


def _mutate_npz(rng: np.random.Generator, raw: bytes) -> bytes:
    """Replace or drop one array of an .npz with a random (wrong) one."""
    with np.load(io.BytesIO(raw), allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    key = sorted(arrays)[int(rng.integers(len(arrays)))]
    choices: list[Any] = [
        None,
        np.zeros(0),
        np.array("{}"),
        np.array("not json"),
        np.full((3, 2), np.nan),
        np.zeros((2, 2, 2)),
        np.array([1 + 1j]),
        np.array([True, False]),
        np.arange(-5, 5),
        np.array(json.dumps({"format": "x", "format_version": 2})),
    ]
    value = choices[int(rng.integers(len(choices)))]
    if value is None:
        del arrays[key]
    else:
        arrays[key] = value
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


# ------------------------------------------------------------------- policy inputs
_POLICIES: dict[str, Any] = {}


def _bad_input(rng: np.random.Generator) -> Any:
    table: list[Any] = [
        "1.0 2.0",
        ["1", "2"],
        [1.0, float("nan")],
        [float("inf"), 0.0],
        np.array([1 + 1j, 0]),
        [True, False],
        [1.0, 2.0, 3.0],
        np.zeros((2, 2, 2)),
        np.zeros((0, 2)),
        [[1.0, 2.0], [3.0]],
        None,
        {"x": 1},
        object(),
        torch.tensor([1.0, 2.0], requires_grad=True),
        torch.tensor([1.0, float("nan")]),
        rng.uniform(-5, 5, 2),
    ]
    return table[int(rng.integers(len(table)))]


def _bad_count(rng: np.random.Generator) -> Any:
    table: list[Any] = [0, -1, 2.0, "3", True, None, 10**12, np.int64(2), 3]
    return table[int(rng.integers(len(table)))]


def _policy_case(rng: np.random.Generator) -> Callable[[], Any]:
    if not _POLICIES:
        _POLICIES.update(dp=_dp(), act=_act(), bc=BCPolicy(BCConfig(hidden=(4,), epochs=1)))
    which = ("dp", "act", "bc")[int(rng.integers(3))]
    policy = _POLICIES[which]
    obs = _bad_input(rng)
    if which == "bc":
        return lambda: policy(obs)
    gens: list[Any] = [None, np.random.default_rng(0), 0, torch.Generator(), np.random.RandomState(0)]
    gen = gens[int(rng.integers(len(gens)))]
    n = _bad_count(rng)
    if which == "dp" and rng.random() < 0.3:
        ts: list[Any] = [5, -1, 100, 2.5, torch.tensor(3), torch.tensor(3.0), "5"]
        t = ts[int(rng.integers(len(ts)))]
        x = torch.zeros(2, 8, 2) if rng.random() < 0.5 else obs
        return lambda: policy.predict_noise(x, t, policy.encode_obs([0.0, 0.0]))
    return lambda: policy.sample(obs, n, generator=gen)


def _record_case(rng: np.random.Generator) -> Callable[[], Any]:
    record: dict[str, Any] = {
        "policy": "act",
        "config": _act().config.to_dict(),
        "training": {"settings": {"steps": 4}, "losses": [[2, 1.0]], "threads": 1, "data": {}},
    }
    part = (record, record["config"], record["training"], record["training"]["settings"])[int(rng.integers(4))]
    keys = [*sorted(part), "unknown"]
    part[keys[int(rng.integers(len(keys)))]] = _JSON_VALUES[int(rng.integers(len(_JSON_VALUES)))]
    return lambda: read_record(record)


# ------------------------------------------------------------------------------ run
def _check_loaded(value: Any) -> None:
    model = getattr(value, "model", None) or getattr(value, "net", None)
    if isinstance(value, ModeClassifier):
        model = value
    if isinstance(model, torch.nn.Module):
        assert all(bool(torch.isfinite(t).all()) for t in model.state_dict().values() if t.is_floating_point())


def test_fuzz_file_boundaries() -> None:
    rng = np.random.default_rng(int(os.environ.get("STEER_FUZZ_SEED", "20240915")))
    counts: Counter[str] = Counter()
    other: list[str] = []
    old = signal.signal(signal.SIGALRM, _alarm)
    torch.set_num_threads(1)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            files = _files(folder)
            kinds = sorted(files)
            for case in range(CASES):
                roll = rng.random()
                expected: tuple[type[BaseException], ...]
                if roll < 0.55:
                    kind = kinds[int(rng.integers(len(kinds)))]
                    raw, load, error = files[kind]
                    if kind in ("dp", "act", "bc", "clf") and rng.random() < 0.4:
                        data = _mutate_header(rng, raw, "glide_classifier" if kind == "clf" else "config")
                    elif kind in ("traj", "walk", "cf") and rng.random() < 0.4:
                        data = _mutate_npz(rng, raw)
                    else:
                        data = _damage(rng, raw)
                    path = folder / f"case{case}{'.safetensors' if error is CheckpointError else '.npz'}"
                    path.write_bytes(data)
                    call: Callable[[], Any] = lambda load=load, path=path: load(path)  # noqa: E731
                    expected, label = (error,), f"{kind} file"
                elif roll < 0.85:
                    call, expected, label = _policy_case(rng), (TypeError, ValueError), "policy input"
                else:
                    call, expected, label = _record_case(rng), (ValueError,), "training record"
                signal.setitimer(signal.ITIMER_REAL, PER_CASE_S)
                try:
                    result = call()
                    _check_loaded(result)
                    counts[f"{label}: accepted"] += 1
                except _Hang:
                    counts["hang"] += 1
                except expected as err:
                    counts[f"{label}: {type(err).__name__}"] += 1
                except BaseException as err:
                    counts["other"] += 1
                    other.append(f"case {case} ({label}): {type(err).__name__}: {err}")
                finally:
                    signal.setitimer(signal.ITIMER_REAL, 0)
            counts.update(_kill_writers(folder))
    finally:
        signal.signal(signal.SIGALRM, old)
    total = sum(v for k, v in counts.items() if not k.startswith("kill"))
    print(f"\nfuzz_files: {total} cases, {dict(sorted(counts.items()))}")
    for line in other[:20]:
        print("  ", line)
    assert total >= 500
    assert counts["hang"] == 0 and counts["other"] == 0, other[:5]
    assert counts["kill: torn"] == 0


def _kill_writers(folder: Path) -> Counter[str]:
    """Kill children writing a 1 MB file at random moments: the target is always the old or the new file."""
    counts: Counter[str] = Counter()
    ctx = multiprocessing.get_context("fork")
    target = folder / "killed.bin"
    old, new = b"o" * 2**20, b"n" * 2**20
    atomic_write_bytes(target, old)
    rng = np.random.default_rng(7)
    for _ in range(KILLS):

        def child() -> None:
            for _ in range(50):
                atomic_write_bytes(target, new)
                atomic_write_bytes(target, old)
            os._exit(0)

        proc = ctx.Process(target=child)
        proc.start()
        time.sleep(float(rng.uniform(0.0, 0.05)))
        proc.kill()
        proc.join()
        content = target.read_bytes()
        counts["kill: intact" if content in (old, new) else "kill: torn"] += 1
    atomic_write_bytes(target, old)
    leftovers = [p for p in folder.iterdir() if p.name.startswith(".killed.bin.")]
    counts["kill: leftovers after the next write"] += len(leftovers)
    assert not leftovers
    return counts
