"""Checked bytes: checkpoints, training states, training records and datasets refuse bytes that changed after
they were written, naming the file; files written before checksums were kept still load."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from safetensors.torch import load as st_load

from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.bc import BCConfig, BCPolicy
from steer_envs.baselines.common.checkpoint import (
    CHECKSUM_KEY,
    METADATA_CHECKSUM_KEY,
    RECORD_CHECKSUM_KEY,
    add_checksum,
    metadata_digest,
    read_record,
    read_safetensors,
    tensors_digest,
    write_record,
    write_safetensors,
)
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.factory import load_policy
from steer_envs.baselines.glide.classifier import ModeClassifier
from steer_envs.baselines.pretrained import CHECKPOINTS, checkpoint_path, checkpoint_record, load_pretrained
from steer_envs.baselines.training import main
from steer_envs.baselines.training.run_state import RUN_FILE, STATE_FILE
from steer_envs.data.datasets import load_dataset
from steer_envs.data.shards import ShardCache
from steer_envs.data.trajectories import TrajectoryDataset, load_trajectories, save_trajectories
from steer_envs.io import CheckpointError, DatasetError, read_npz

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "baselines" / "checkpoints"
TINY_DP = ["--model", "horizon=8", "--model", "down_dims=[8,16]", "--model", "step_embed_dim=16", "--model"]
TINY_DP += ["relative=false"]


# --------------------------------------------------------------------------- helpers
def _split(raw: bytes) -> tuple[dict[str, Any], int]:
    """A safetensors file's header and where its data begins."""
    n = int.from_bytes(raw[:8], "little")
    return json.loads(raw[8 : 8 + n]), 8 + n


def _join(header: dict[str, Any], data: bytes) -> bytes:
    text = json.dumps(header).encode()
    return len(text).to_bytes(8, "little") + text + data


def _flip(path: Path, count: int = 1, prefix: str = "") -> str:
    """Flip the lowest bit of ``count`` bytes in the middle of the largest tensor (named ``prefix...``): the header
    stays intact and the values finite (a float32's low mantissa bits), so only a checksum can tell. Its name."""
    raw = bytearray(path.read_bytes())
    header, start = _split(bytes(raw))
    entries = {k: v for k, v in header.items() if k != "__metadata__" and k.startswith(prefix)}
    name = max(entries, key=lambda k: entries[k]["data_offsets"][1] - entries[k]["data_offsets"][0])
    begin, stop = entries[name]["data_offsets"]
    floats = (stop - begin) // 4  # flip the first byte of float32s (their lowest mantissa bits), spread evenly
    for index in {floats * (2 * i + 1) // (2 * count) for i in range(count)}:
        raw[start + begin + 4 * index] ^= 0x01
    path.write_bytes(bytes(raw))
    return name


def _strip_checksum(path: Path) -> None:
    """Make ``path`` a file as written before checksums were kept (same tensors, no checksum)."""
    raw = path.read_bytes()
    header, start = _split(raw)
    del header["__metadata__"][CHECKSUM_KEY]
    header["__metadata__"].pop(METADATA_CHECKSUM_KEY, None)
    path.write_bytes(_join(header, raw[start:]))


def _dp() -> DiffusionPolicy:
    return DiffusionPolicy(DiffusionConfig(obs_dim=2, action_dim=2, horizon=8, down_dims=(8, 16), step_embed_dim=8))


def _bc() -> BCPolicy:
    policy = BCPolicy(BCConfig(hidden=(8,), epochs=1, standardize=True))
    policy.fit(np.random.default_rng(0).uniform(-1, 1, (16, 2)), np.zeros((16, 2)))
    return policy


WRITERS = {
    "dp": (lambda path: _dp().save(path), load_policy),
    "act": (
        lambda path: ACTPolicy(ACTConfig(obs_dim=2, action_dim=2, chunk_size=4, d_model=8, n_heads=1)).save(path),
        load_policy,
    ),
    "bc": (lambda path: _bc().save(path), BCPolicy.load),
    "classifier": (lambda path: ModeClassifier(2, 3, hidden=4, n_heads=2).save(path), ModeClassifier.load),
}


# --------------------------------------------------------------------- checkpoints
def test_every_shipped_checkpoint_and_record_carries_its_checksum() -> None:
    files = sorted(SHIPPED.glob("*/*.safetensors"))
    assert len(files) >= 5
    for path in files:
        raw = path.read_bytes()
        header, start = _split(raw)
        stored = header["__metadata__"].get(CHECKSUM_KEY)
        assert stored == tensors_digest(header, raw[start:]), (
            f"{path} has no valid {CHECKSUM_KEY}: give it one with "
            "steer_envs.baselines.common.checkpoint.add_checksum (its tensors stay as they are)"
        )
        stored = header["__metadata__"].get(METADATA_CHECKSUM_KEY)
        assert stored == metadata_digest(header["__metadata__"]), f"{path}: add_checksum it (its metadata's)"
        record = path.with_suffix(".json")
        assert RECORD_CHECKSUM_KEY in json.loads(record.read_text()), f"{record}: add_checksum it"
        read_record(record)


@pytest.mark.parametrize("name", sorted(CHECKPOINTS))
def test_a_flipped_bit_in_a_shipped_checkpoint_is_refused_naming_the_file(name: str, tmp_path: Path) -> None:
    copy = tmp_path / f"copy-of-{name}.safetensors"
    shutil.copyfile(checkpoint_path(name), copy)
    load_pretrained(name, checkpoint=copy)  # the copy as it is loads
    tensor = _flip(copy)
    with pytest.raises(CheckpointError, match=rf"{copy.name}: damaged: its tensors' bytes do not match") as err:
        load_pretrained(name, checkpoint=copy)
    assert "restore it from a good copy" in str(err.value), tensor
    with pytest.raises(CheckpointError, match=copy.name):
        load_policy(copy)
    # its metadata: one changed digit of the normalization statistics is refused, the header still parsing
    shutil.copyfile(checkpoint_path(name), copy)
    raw = copy.read_bytes()
    header, start = _split(raw)
    config = header["__metadata__"]["config"]
    where = config.index('"stats"')
    digit = next(i for i in range(where, len(config)) if config[i] in "123456789")
    header["__metadata__"]["config"] = config[:digit] + str(int(config[digit]) % 9 + 1) + config[digit + 1 :]
    copy.write_bytes(_join(header, raw[start:]))
    with pytest.raises(CheckpointError, match=rf"{copy.name}: damaged: its metadata \(config, normalization\)"):
        load_pretrained(name, checkpoint=copy)
    # its record: one changed number is refused too
    record = json.loads(checkpoint_path(name).with_suffix(".json").read_text())
    record["training"]["losses"][-1][1] += 1e-9
    (changed := tmp_path / "copy.json").write_text(json.dumps(record, indent=1))
    assert checkpoint_record(name)["training"]["losses"] != record["training"]["losses"]
    with pytest.raises(CheckpointError, match=r"copy\.json: damaged or edited"):
        read_record(changed)


@pytest.mark.parametrize("kind", sorted(WRITERS))
def test_every_checkpoint_writer_stores_a_checksum_that_loading_checks(kind: str, tmp_path: Path) -> None:
    write, load = WRITERS[kind]
    path = write(tmp_path / f"{kind}.safetensors")
    header, _ = _split(path.read_bytes())
    assert len(header["__metadata__"][CHECKSUM_KEY]) == 64
    assert header["__metadata__"][METADATA_CHECKSUM_KEY] == metadata_digest(header["__metadata__"])
    load(path)
    _flip(path, count=16)
    with pytest.raises(CheckpointError, match=rf"{kind}\.safetensors: damaged"):
        load(path)


def test_changed_tensor_bytes_behind_an_intact_header(tmp_path: Path) -> None:
    """Every change of the tensors is caught, whatever it does to their values; the header alone is not enough."""
    path = _dp().save(tmp_path / "dp.safetensors")
    good = path.read_bytes()
    header, start = _split(good)
    entries = {k: v for k, v in header.items() if k != "__metadata__"}
    # two tensors of one shape swapped in the header: valid offsets, every tensor finite, the wrong weights
    by_shape: dict[str, list[str]] = {}
    for name, entry in entries.items():
        by_shape.setdefault(json.dumps([entry["dtype"], entry["shape"]]), []).append(name)
    a, b = next(names for names in by_shape.values() if len(names) >= 2)[:2]
    swapped = json.loads(json.dumps(header))
    swapped[a]["data_offsets"], swapped[b]["data_offsets"] = header[b]["data_offsets"], header[a]["data_offsets"]
    path.write_bytes(_join(swapped, good[start:]))
    with pytest.raises(CheckpointError, match="damaged"):
        load_policy(path)
    # a flipped bit that makes a weight infinite: named as damaged, with the tensor it hit
    raw = bytearray(good)
    first = min(entries.values(), key=lambda v: v["data_offsets"][0])
    raw[start + first["data_offsets"][0] : start + first["data_offsets"][0] + 4] = np.float32(np.inf).tobytes()
    path.write_bytes(bytes(raw))
    with pytest.raises(CheckpointError, match=r"damaged: .*now holds NaN or infinite values"):
        load_policy(path)
    # a checksum that is not one, or another file's
    for value in ("abc", "0" * 64):
        changed = json.loads(json.dumps(header))
        changed["__metadata__"][CHECKSUM_KEY] = value
        path.write_bytes(_join(changed, good[start:]))
        with pytest.raises(CheckpointError, match="not a sha256 hex digest" if value == "abc" else "damaged"):
            load_policy(path)


def test_files_written_before_checksums_load_and_can_be_given_one(tmp_path: Path) -> None:
    path = _dp().save(tmp_path / "dp.safetensors")
    _strip_checksum(path)
    legacy = path.read_bytes()
    assert CHECKSUM_KEY not in _split(legacy)[0]["__metadata__"]
    weights = load_policy(path).model.state_dict()  # no checksum: loads as before
    assert add_checksum(path) is True
    again = path.read_bytes()
    assert again[_split(again)[1] :] == legacy[_split(legacy)[1] :]  # the tensors' bytes as they were
    assert all(torch.equal(weights[k], v) for k, v in load_policy(path).model.state_dict().items())
    assert add_checksum(path) is False  # already has one: verified, kept
    assert st_load(again).keys() == st_load(legacy).keys()
    _flip(path)
    with pytest.raises(CheckpointError, match="damaged"):
        add_checksum(path)
    with pytest.raises(ValueError, match=r"\.safetensors or \.json"):
        add_checksum(tmp_path / "x.npz")
    with pytest.raises(ValueError, match="reserved"):
        write_safetensors(tmp_path / "y.safetensors", {"w": torch.ones(1)}, CHECKSUM_KEY, {})


def test_training_records(tmp_path: Path) -> None:
    path = write_record(tmp_path / "r.json", {"policy": "dp", "training": {"losses": [[1, 0.5]], "k": (1, 2)}})
    assert read_record(path) == {"policy": "dp", "training": {"losses": [[1, 0.5]], "k": [1, 2]}}
    text = json.loads(path.read_text())
    text["training"]["losses"][0][1] = 0.25
    path.write_text(json.dumps(text))
    with pytest.raises(CheckpointError, match=r"r\.json: damaged or edited.*delete the 'sha256' entry"):
        read_record(path)
    del text[RECORD_CHECKSUM_KEY]  # an edit accepted by hand, or a record written before checksums
    path.write_text(json.dumps(text))
    assert read_record(path)["training"]["losses"] == [[1, 0.25]]
    assert add_checksum(path) is True and add_checksum(path) is False
    assert read_record(path)["training"]["losses"] == [[1, 0.25]]
    with pytest.raises(TypeError, match="JSON-serializable"):
        write_record(tmp_path / "bad.json", {"x": object()})


# ------------------------------------------------------------------ training state
@pytest.fixture(scope="module")
def data_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(0)
    data = TrajectoryDataset(rng.normal(size=(200, 3)), rng.normal(size=(200, 2)), meta={"domain": "toy"})
    return save_trajectories(data, tmp_path_factory.mktemp("data") / "toy.npz")


def test_a_damaged_training_state_stops_resume_naming_the_file(data_file: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    argv = ["--policy", "dp", "--dataset", str(data_file), *TINY_DP, "--steps", "6", "--no-progress"]
    assert main([*argv, "--train", "batch_size=4", "--run-dir", str(run)]) == 0
    state = run / STATE_FILE
    assert len(_split(state.read_bytes())[0]["__metadata__"][CHECKSUM_KEY]) == 64
    assert RECORD_CHECKSUM_KEY in json.loads((run / RUN_FILE).read_text())
    good = state.read_bytes()
    _flip(state, count=16, prefix="model.")
    cmd = [sys.executable, "-m", "steer_envs.baselines.training", "--resume", str(run), "--no-progress"]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert f"{state}: damaged" in proc.stderr and "delete it and `--resume`" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    # a state saved before checksums were kept (the same bytes, no checksum) still resumes
    state.write_bytes(good)
    _strip_checksum(state)
    before = (run / "dp.safetensors").read_bytes()
    assert main(["--resume", str(run), "--no-progress"]) == 0
    assert (run / "dp.safetensors").read_bytes() == before
    tensors, meta = read_safetensors(state, "training_state")
    assert meta["step"] == 6 and tensors


# ----------------------------------------------------------------------- datasets
def _flip_npz_member(path: Path, member: str | None = None) -> None:
    """Flip one bit in the middle of an archive member's stored bytes (default: the largest member); every header
    of the archive stays intact."""
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo(member) if member else max(archive.infolist(), key=lambda i: i.compress_size)
    raw = bytearray(path.read_bytes())
    local = info.header_offset  # the local header: 30 bytes, then its own name and extra field
    start = local + 30 + int.from_bytes(raw[local + 26 : local + 28], "little")
    start += int.from_bytes(raw[local + 28 : local + 30], "little")
    raw[start + info.compress_size // 2] ^= 0x01
    path.write_bytes(bytes(raw))


def test_a_flipped_bit_in_a_dataset_is_refused_naming_the_file(data_file: Path, tmp_path: Path) -> None:
    copy = shutil.copyfile(data_file, tmp_path / "copy.npz")
    assert load_dataset(copy).observations.shape == (200, 3)
    _flip_npz_member(copy, "observations.npy")
    with pytest.raises(DatasetError, match=r"copy\.npz: damaged: array 'observations' does not match the CRC-32"):
        load_dataset(copy)
    with pytest.raises(DatasetError, match="write it again"):
        load_trajectories(copy)


def test_a_damaged_cached_shard_is_refused_and_rebuilt(tmp_path: Path) -> None:
    built: list[int] = []

    def build(seed: int) -> list[TrajectoryDataset]:
        built.append(seed)
        rng = np.random.default_rng(seed)
        return [TrajectoryDataset(rng.normal(size=(500, 4)), rng.normal(size=(500, 2)))]

    cache: ShardCache[int, TrajectoryDataset] = ShardCache(
        tmp_path,
        name=lambda seed: f"shard-{seed}.npz",
        build=build,
        load=lambda path: [load_trajectories(path)],
        save=lambda path, records, meta: save_trajectories(records[0], path),
    )
    records, path, _ = cache.ensure(3)
    arrays = dict(np.load(path))
    _flip_npz_member(path)
    with pytest.raises(DatasetError, match=rf"{path.name}: damaged"):
        load_trajectories(path)
    again, _, rebuilt = cache.ensure(3)  # a damaged shard is a missing one: built again
    assert rebuilt and built == [3, 3]
    assert np.array_equal(again[0].observations, records[0].observations)
    assert all(np.array_equal(v, dict(np.load(path))[k]) for k, v in arrays.items())


def test_stray_bytes_after_an_array_are_refused(tmp_path: Path) -> None:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.arange(4.0))
    path = tmp_path / "stray.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("x.npy", buf.getvalue() + b"\x00" * 16)
    with pytest.raises(DatasetError, match=r"stray\.npz: array 'x' is followed by stray bytes"):
        read_npz(path)


# ---------------------------------------------------------------- SB3 checkpoints
def test_a_damaged_sb3_checkpoint_is_refused_before_sb3_reads_it(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    from steer_envs.baselines.sb3 import CHECKPOINT, Sb3Settings, run_folder, train_and_evaluate

    env_id = "steer_envs/Maze2D-UmazeDense-v0"
    options = {"eval_every": 10, "eval_episodes": 1, "max_episode_steps": 5, "cache": tmp_path}
    assert train_and_evaluate(env_id, "sac", 0, Sb3Settings(timesteps=10, **options)).timesteps == 10
    folder = run_folder(env_id, "sac", 0, Sb3Settings(timesteps=10, **options)) / CHECKPOINT
    buffer, state_file = folder / "replay_buffer.pkl", folder / "state.json"
    good = buffer.read_bytes()
    raw = bytearray(good)
    raw[len(raw) // 2] ^= 0x01
    buffer.write_bytes(bytes(raw))
    longer = Sb3Settings(timesteps=20, **options)
    with pytest.raises(CheckpointError, match=rf"{buffer}: damaged or missing.*delete {folder} to train"):
        train_and_evaluate(env_id, "sac", 0, longer)
    # a checkpoint written before the checksums were kept continues as before
    buffer.write_bytes(good)
    state = json.loads(state_file.read_text())
    del state["sha256"]
    state_file.write_text(json.dumps(state))
    assert train_and_evaluate(env_id, "sac", 0, longer).resumed_from == 10
    state_file.write_text("[1, 2]")
    with pytest.raises(CheckpointError, match=r"state\.json: not a checkpoint state"):
        train_and_evaluate(env_id, "sac", 0, longer)
