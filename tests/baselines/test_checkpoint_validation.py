"""Checkpoint and training-record files: every loader checks before it builds and raises CheckpointError."""

from __future__ import annotations

import json
import struct
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from safetensors.torch import save as st_save

from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.bc import BCConfig, BCPolicy
from steer_envs.baselines.common import CheckpointError, read_checkpoint
from steer_envs.baselines.common.checkpoint import CHECKSUM_KEY, METADATA_CHECKSUM_KEY, metadata_digest
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.factory import load_policy
from steer_envs.baselines.glide.classifier import ModeClassifier
from steer_envs.baselines.pretrained import checkpoint_path, load_pretrained
from steer_envs.baselines.training import check_record
from steer_envs.data.trajectories import TrajectoryDataset

TINY_DP = {"horizon": 8, "down_dims": (8, 16), "obs_embed_dim": 8, "step_embed_dim": 8}
TINY_ACT = {"chunk_size": 4, "d_model": 8, "n_heads": 1, "dim_feedforward": 8, "latent_dim": 4}


def _dp() -> DiffusionPolicy:
    return DiffusionPolicy(DiffusionConfig(obs_dim=2, action_dim=2, **TINY_DP))


def _act() -> ACTPolicy:
    return ACTPolicy(ACTConfig(obs_dim=2, action_dim=2, **TINY_ACT))


def _split(raw: bytes) -> tuple[dict[str, Any], bytes]:
    n = int.from_bytes(raw[:8], "little")
    return json.loads(raw[8 : 8 + n]), raw[8 + n :]


def _join(header: dict[str, Any], data: bytes) -> bytes:
    """The file of ``header`` and ``data``, its metadata checksum renewed: a consistently written foreign file,
    so the checks behind the checksum are the ones tested."""
    meta = header.get("__metadata__")
    if isinstance(meta, dict) and METADATA_CHECKSUM_KEY in meta:
        meta[METADATA_CHECKSUM_KEY] = metadata_digest(meta)
    text = json.dumps(header).encode()
    return struct.pack("<Q", len(text)) + text + data


def _rewrite(path: Path, edit: Callable[[dict[str, Any]], None]) -> Path:
    """Change the JSON config inside the safetensors metadata of ``path``."""
    header, data = _split(path.read_bytes())
    meta = json.loads(header["__metadata__"]["config"])
    edit(meta)
    header["__metadata__"]["config"] = json.dumps(meta)
    path.write_bytes(_join(header, data))
    return path


@pytest.fixture(params=["dp", "act"])
def saved(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[type, Path]:
    policy = _dp() if request.param == "dp" else _act()
    return type(policy), policy.save(tmp_path / f"{request.param}.safetensors")


# --------------------------------------------------------------------------- damage
def test_truncated_file(saved: tuple[type, Path]) -> None:
    cls, path = saved
    raw = path.read_bytes()
    for cut in (3, 100, len(raw) // 2, len(raw) - 1):
        path.write_bytes(raw[:cut])
        with pytest.raises(CheckpointError, match=rf"{path.name}.*truncated"):
            cls.load(path)
        with pytest.raises(CheckpointError, match=path.name):
            load_policy(path)


def test_foreign_and_garbage_files(tmp_path: Path) -> None:
    plain = tmp_path / "plain.safetensors"
    plain.write_bytes(st_save({"w": torch.zeros(2)}))
    with pytest.raises(CheckpointError, match="no 'config' metadata"):
        load_policy(plain)
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00{not json at all}")
    with pytest.raises(CheckpointError, match="not JSON"):
        read_checkpoint(junk)
    with pytest.raises(CheckpointError, match="no checkpoint file"):
        load_policy(tmp_path / "missing.safetensors")
    assert issubclass(CheckpointError, ValueError)


def test_wrong_shape_and_dtype_and_names(tmp_path: Path) -> None:
    policy = _dp()
    state = policy.model.state_dict()
    header = {"format": "steer_envs.baselines.policy/2", "policy": "dp", "config": policy.config.to_dict()}
    header["stats"] = {k: v.to_dict() for k, v in policy.stats.items()}
    name = next(iter(state))

    def write(tensors: dict[str, torch.Tensor]) -> Path:
        path = tmp_path / "x.safetensors"
        path.write_bytes(st_save(tensors, metadata={"config": json.dumps(header)}))
        return path

    swapped = dict(state)
    swapped[name] = state[name].flatten()  # same count, another shape
    with pytest.raises(CheckpointError, match=rf"tensor '{name}' has shape"):
        DiffusionPolicy.load(write(swapped))
    double = {k: v.double() for k, v in state.items()}
    with pytest.raises(CheckpointError, match=r"dtype torch.float64"):
        DiffusionPolicy.load(write(double))
    renamed = {("x" + k if k == name else k): v for k, v in state.items()}
    with pytest.raises(CheckpointError, match=r"do not match the network.*missing"):
        DiffusionPolicy.load(write(renamed))
    fewer = {k: v for k, v in state.items() if k != name}
    with pytest.raises(CheckpointError, match=r"implies .* weights but the file holds"):
        DiffusionPolicy.load(write(fewer))


def test_nan_weights_are_refused_on_load_and_on_save(saved: tuple[type, Path]) -> None:
    cls, path = saved
    header, data = _split(path.read_bytes())
    first = min((v for k, v in header.items() if k != "__metadata__"), key=lambda v: v["data_offsets"][0])
    start = len(path.read_bytes()) - len(data) + first["data_offsets"][0]
    raw = bytearray(path.read_bytes())
    raw[start : start + 4] = struct.pack("<f", float("nan"))
    path.write_bytes(bytes(raw))
    with pytest.raises(CheckpointError, match="NaN or infinite"):
        cls.load(path)
    policy = _dp()
    with torch.no_grad():
        next(iter(policy.model.parameters())).fill_(float("inf"))
    with pytest.raises(ValueError, match="NaN or infinite"):
        policy.save(path.with_name("inf.safetensors"))
    assert not path.with_name("inf.safetensors").exists()


def test_huge_config_is_refused_before_allocating(saved: tuple[type, Path]) -> None:
    """A config claiming a 51 GB network in a small file is refused in milliseconds."""
    cls, path = saved
    huge: dict[str, Any] = {"down_dims": [65536] * 3} if cls is DiffusionPolicy else {"d_model": 65536}
    _rewrite(path, lambda meta: meta["config"].update(huge))
    start = time.perf_counter()
    with pytest.raises(CheckpointError, match=r"implies a network of .* parameters"):
        cls.load(path)
    assert time.perf_counter() - start < 1.0


def test_config_that_fits_nothing_it_names(saved: tuple[type, Path]) -> None:
    cls, path = saved
    _rewrite(path, lambda meta: meta["config"].update({"obs_dim": 3}))  # a few more weights than the file holds
    with pytest.raises(CheckpointError, match="implies"):
        cls.load(path)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda m: m.update(format="other/1"), "format 'other/1'"),
        (lambda m: m.update(policy="act"), "holds a 'act' policy"),
        (lambda m: m.update(config="nope"), "malformed"),
        (lambda m: m["config"].update(horizon="64"), "malformed.*horizon must be an int"),
        (lambda m: m["config"].update(unknown_field=1), "malformed.*unknown_field"),
        (lambda m: m.pop("stats"), "malformed"),
        (lambda m: m.update(stats={"observation": {"min": ["a"], "max": [1]}}), "real numbers"),
        (lambda m: m.update(stats={"observation": {"min": [0.0, 0.0], "max": [float("nan"), 1.0]}}), "finite"),
        (lambda m: m.update(extra=[1, 2]), "'extra' must be a JSON object"),
    ],
)
def test_malformed_headers(tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str) -> None:
    path = _rewrite(_dp().save(tmp_path / "dp.safetensors"), edit)
    with pytest.raises(CheckpointError, match=match):
        DiffusionPolicy.load(path)


def test_factory_and_pretrained_loaders(tmp_path: Path) -> None:
    path = _act().save(tmp_path / "act.safetensors")
    assert isinstance(load_pretrained("act", checkpoint=path), ACTPolicy)
    with pytest.raises(CheckpointError, match="holds a 'act' policy, expected 'dp'"):
        load_pretrained("dp", checkpoint=path)
    with pytest.raises(ValueError, match="name must be one of"):
        load_pretrained("xx", checkpoint=path)
    with pytest.raises(TypeError, match="device"):
        load_policy(path, device=3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="device"):
        load_policy(path, device="no-such-device")
    assert checkpoint_path("dp").is_file()


# ------------------------------------------------------------------ BC and GLiDE
def test_bc_checkpoint_validation(tmp_path: Path) -> None:
    policy = BCPolicy(BCConfig(hidden=(8,), epochs=1, standardize=True))
    policy.fit(np.random.default_rng(0).uniform(-1, 1, (32, 2)), np.zeros((32, 2)))
    path = policy.save(tmp_path / "bc.safetensors")
    np.testing.assert_array_equal(BCPolicy.load(path)(np.ones((3, 2))), policy(np.ones((3, 2))))
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) - 10])
    with pytest.raises(CheckpointError, match="truncated"):
        BCPolicy.load(path)
    path.write_bytes(raw)
    _rewrite(path, lambda m: m["config"].update(hidden=[65536] * 40))
    with pytest.raises(CheckpointError, match="implies"):
        BCPolicy.load(path)
    path.write_bytes(raw)
    _rewrite(path, lambda m: m.update(seed="0"))
    with pytest.raises(CheckpointError, match=r"malformed BCPolicy header.*seed"):
        BCPolicy.load(path)
    header, _ = _split(raw)
    tensors = {k: v for k, v in header.items() if k != "__metadata__"}
    meta = {k: v for k, v in header["__metadata__"].items() if k != CHECKSUM_KEY}  # other tensors: no checksum
    bad_scale = {**{k: torch.zeros(v["shape"]) for k, v in tensors.items()}, "input_scale": torch.zeros(2)}
    path.write_bytes(st_save(bad_scale, metadata=meta))
    with pytest.raises(CheckpointError, match="input_scale must be > 0"):
        BCPolicy.load(path)
    one = {k: torch.zeros(v["shape"]) for k, v in tensors.items() if k != "input_scale"}
    path.write_bytes(st_save(one, metadata=meta))
    with pytest.raises(CheckpointError, match="only one of input_mean and input_scale"):
        BCPolicy.load(path)


def test_glide_classifier_cache_validation(tmp_path: Path) -> None:
    clf = ModeClassifier(2, 3, hidden=8, n_heads=2)
    path = clf.save(tmp_path / "clf.safetensors", extra={"note": "x"})
    assert ModeClassifier.load(path).n_heads == 2
    raw = path.read_bytes()
    header, data = _split(raw)
    meta = json.loads(header["__metadata__"]["glide_classifier"])

    def write_meta(**changes: Any) -> Path:
        h = json.loads(json.dumps(header))
        h["__metadata__"]["glide_classifier"] = json.dumps({**meta, **changes})
        path.write_bytes(_join(h, data))
        return path

    with pytest.raises(CheckpointError, match="implies a network"):
        ModeClassifier.load(write_meta(hidden=10**9))
    with pytest.raises(CheckpointError, match=r"malformed GLiDE classifier metadata.*head"):
        ModeClassifier.load(write_meta(head=5))
    with pytest.raises(CheckpointError, match=r"malformed.*state_dim"):
        ModeClassifier.load(write_meta(state_dim="2"))
    path.write_bytes(raw[:-7])
    with pytest.raises(CheckpointError, match="truncated"):
        ModeClassifier.load(path)
    path.write_bytes(st_save({"w": torch.zeros(1)}))
    with pytest.raises(CheckpointError, match="no 'glide_classifier' metadata"):
        ModeClassifier.load(path)


# ------------------------------------------------------------- training records
def _record(tmp_path: Path) -> tuple[Path, TrajectoryDataset]:
    data = TrajectoryDataset(np.random.default_rng(0).normal(size=(60, 2)), np.zeros((60, 2)), meta={"seed": 1})
    record = {
        "policy": "act",
        "config": ACTConfig(obs_dim=2, action_dim=2, **TINY_ACT).to_dict(),
        "training": {
            "settings": {"steps": 4, "batch_size": 4, "log_every": 2},
            "losses": [[2, 1.0], [4, 0.5]],
            "threads": 1,
            "data": {"seed": 1},
        },
    }
    path = tmp_path / "act.json"
    path.write_text(json.dumps(record))
    return path, data


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda r: r.pop("training"), "missing 'training'"),
        (lambda r: r.update(policy="nope"), "policy must be one of"),
        (lambda r: r["training"].update(losses=[[2, "x"]]), "losses"),
        (lambda r: r["training"].update(losses=[[2, float("nan")]]), "finite"),
        (lambda r: r["training"].update(losses=[[4, 1.0], [2, 1.0]]), "increase"),
        (lambda r: r["training"].update(threads=10**9), "threads"),
        (lambda r: r["training"]["settings"].update(batch_size=10**12), "batch_size"),
        (lambda r: r["config"].update(d_model=2**20), "implies"),
    ],
)
def test_malformed_training_records(tmp_path: Path, edit: Callable[[dict[str, Any]], None], match: str) -> None:
    path, data = _record(tmp_path)
    record = json.loads(path.read_text())
    edit(record)
    path.write_text(json.dumps(record))
    with pytest.raises(CheckpointError, match=match):
        check_record(path, data, 2)


def test_record_files_that_are_not_records(tmp_path: Path) -> None:
    path, data = _record(tmp_path)
    assert check_record(path, data, 2)["policy"] == "act"
    for text in ("[]", "{not json", ""):
        path.write_text(text)
        with pytest.raises(CheckpointError, match=path.name):
            check_record(path, data, 2)
    with pytest.raises(CheckpointError, match="no training record"):
        check_record(tmp_path / "missing.json", data, 2)


# --------------------------------------------------------------------- properties
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cut=st.integers(0, 4000),
    flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(1, 255)), max_size=3),
)
def test_damaged_checkpoints_load_or_raise_checkpoint_error(cut: int, flips: list[tuple[int, int]]) -> None:
    raw = bytearray(_DP_BYTES)
    for pos, x in flips:
        raw[pos % len(raw)] ^= x
    data = bytes(raw[: len(raw) - cut])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "dp.safetensors")
        path.write_bytes(data)
        try:
            policy = load_policy(path)
        except CheckpointError as err:
            assert "dp.safetensors" in str(err)
        else:  # only the weights' bytes changed, to finite values
            assert all(bool(torch.isfinite(t).all()) for t in policy.model.state_dict().values())


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-(10**12), 10**12) | st.floats(allow_nan=False) | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=10,
)


@settings(max_examples=60, deadline=None)
@given(field=st.sampled_from([*sorted(DiffusionConfig.field_names()), "stats", "format", "extra"]), value=_JSON)
def test_random_header_values_load_or_raise_checkpoint_error(field: str, value: Any) -> None:
    header, data = _split(_DP_BYTES)
    meta = json.loads(header["__metadata__"]["config"])
    if field in meta:
        meta[field] = value
    else:
        meta["config"][field] = value
    header["__metadata__"]["config"] = json.dumps(meta)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "dp.safetensors")
        path.write_bytes(_join(header, data))
        start = time.perf_counter()
        try:
            DiffusionPolicy.load(path)
        except CheckpointError as err:
            assert "dp.safetensors" in str(err)
        assert time.perf_counter() - start < 5.0


with tempfile.TemporaryDirectory() as _tmp:
    _DP_BYTES = _dp().save(Path(_tmp, "dp.safetensors")).read_bytes()
