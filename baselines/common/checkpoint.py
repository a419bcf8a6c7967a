"""Safetensors checkpoint files: written atomically, read only after every header field has been checked.

A checkpoint is a safetensors file: an 8-byte header length, a JSON header
(each tensor's dtype, shape and byte range, plus string metadata) and the raw
tensor data; loading it runs no code. :func:`read_safetensors` checks, before
any tensor is allocated, that the file exists and is not larger than
:data:`MAX_CHECKPOINT_BYTES`, that the header fits the file, that every
tensor's dtype is known, its shape non-negative and its byte range inside the
data and of the size its shape implies (a truncated file is caught here), that
the ranges tile the data, and that the metadata entry this library writes is
a JSON object; then it loads the tensors and checks that every floating-point
tensor is finite. :func:`check_state` then compares the tensors with the
network they are meant for (names, shapes, dtypes), and
:func:`check_parameter_count` compares the size a config implies with what
the file holds, so a config claiming a huge network is refused before that
network is built. Every problem is a
:class:`~steer_envs.io.CheckpointError` naming the file.

Checked bytes: :func:`write_safetensors` stores the sha256 of the tensors
(:func:`tensors_digest`: each tensor's name, dtype and shape, then its raw
bytes, in name order) in the metadata entry :data:`CHECKSUM_KEY`, and the
sha256 of the other metadata (:func:`metadata_digest`: the config and
normalization statistics, JSON) under :data:`METADATA_CHECKSUM_KEY`;
:func:`read_safetensors` recomputes both, so a file whose tensor bytes or
metadata changed after it was written (a flipped bit on disk, a bad copy) is
refused even when its header still parses. A training record (:func:`write_record`) carries the
sha256 of its JSON content under :data:`RECORD_CHECKSUM_KEY` and is checked
the same way. Files written without a checksum (before it was kept) load as
before; :func:`add_checksum` gives such a file its checksum without changing
its tensors or content (every checkpoint shipped in the package has one).

>>> import tempfile, torch
>>> with tempfile.TemporaryDirectory() as tmp:
...     path = write_safetensors(f"{tmp}/w.safetensors", {"w": torch.ones(2)}, "config", {"format": "demo"})
...     tensors, meta = read_safetensors(path, "config")
>>> tensors["w"].tolist(), meta
([1.0, 1.0], {'format': 'demo'})
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from safetensors.torch import load as st_load
from safetensors.torch import save as st_save

from steer_envs.io import CheckpointError, atomic_open, atomic_write_text

__all__ = [
    "CHECKSUM_KEY",
    "MAX_CHECKPOINT_BYTES",
    "MAX_PARAMETERS",
    "METADATA_CHECKSUM_KEY",
    "RECORD_CHECKSUM_KEY",
    "CheckpointError",
    "add_checksum",
    "check_parameter_count",
    "check_state",
    "metadata_digest",
    "read_record",
    "read_safetensors",
    "tensors_digest",
    "write_record",
    "write_safetensors",
]

#: the largest checkpoint file read (4 GiB): the tensors are read into memory whole
MAX_CHECKPOINT_BYTES = 4 * 2**30
#: the most numbers a loaded network may hold (1e9, 4 GB of float32); a config implying more is refused
MAX_PARAMETERS = 1_000_000_000
#: the largest training record (a checkpoint's ``.json``) read; the shipped ones are a few hundred kB
MAX_RECORD_BYTES = 64 * 2**20
#: safetensors' own header limit is 100 MB; ours are a few kB
_MAX_HEADER_BYTES = 16 * 2**20
#: the safetensors metadata entry holding the hex sha256 of a file's tensors (:func:`tensors_digest`)
CHECKSUM_KEY = "tensors_sha256"
#: the safetensors metadata entry holding the hex sha256 of the file's other metadata (:func:`metadata_digest`)
METADATA_CHECKSUM_KEY = "metadata_sha256"
#: the entry of a training record (a JSON object) holding the hex sha256 of its other entries
RECORD_CHECKSUM_KEY = "sha256"
_HEX_SHA256 = re.compile(r"[0-9a-f]{64}")
#: what to do about a damaged file, unless the caller knows better
_REMEDY = "restore it from a good copy or write it again (a shipped checkpoint: reinstall steer-envs)"
#: safetensors dtype -> bytes per element
_DTYPE_BYTES = {
    "F64": 8,
    "F32": 4,
    "F16": 2,
    "BF16": 2,
    "I64": 8,
    "I32": 4,
    "I16": 2,
    "I8": 1,
    "U8": 1,
    "BOOL": 1,
}


def _source(path: Any) -> Path:
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    if os.fspath(path) == "":
        raise ValueError("path must not be empty")
    return Path(path)


def write_safetensors(
    path: str | os.PathLike[str],
    tensors: Mapping[str, torch.Tensor],
    meta_key: str,
    meta: Mapping[str, Any],
    *,
    sort_keys: bool = False,
) -> Path:
    """Write ``tensors``, the JSON object ``meta`` (under metadata ``meta_key``) and the tensors' checksum
    (under :data:`CHECKSUM_KEY`) atomically; returns the path.

    ``ValueError`` for a path not ending in ``.safetensors`` and for tensors
    holding NaN or infinite values (such a file could not be loaded again).
    """
    out = _source(path)
    if out.suffix != ".safetensors":
        raise ValueError(f"path must end with .safetensors, got {str(out)!r}")
    if meta_key in (CHECKSUM_KEY, METADATA_CHECKSUM_KEY):
        raise ValueError(f"meta_key {meta_key!r} is reserved for a checksum")
    cpu = {}
    for name, value in tensors.items():
        if not isinstance(value, torch.Tensor):
            raise TypeError(f"tensor {name!r} must be a torch.Tensor, got {type(value).__name__}")
        t = value.detach().to("cpu").contiguous()
        if (t.is_floating_point() or t.is_complex()) and not bool(torch.isfinite(t).all()):
            raise ValueError(f"tensor {name!r} holds NaN or infinite values; refusing to write {str(out)!r}")
        cpu[name] = t
    try:
        text = json.dumps(dict(meta), sort_keys=sort_keys)
    except (TypeError, ValueError) as err:
        raise TypeError(f"the checkpoint metadata must be JSON-serializable ({err})") from None
    raw = st_save(cpu, metadata={meta_key: text})
    n = int.from_bytes(raw[:8], "little")
    header = json.loads(raw[8 : 8 + n])
    data = memoryview(raw)[8 + n :]
    metadata = header["__metadata__"]
    metadata[METADATA_CHECKSUM_KEY] = metadata_digest(metadata)
    metadata[CHECKSUM_KEY] = tensors_digest(header, data)
    _write(out, header, data)
    return out


def metadata_digest(metadata: Mapping[str, Any]) -> str:
    """The hex sha256 of a safetensors file's string metadata, its checksum entries left out (sorted JSON).

    >>> metadata_digest({"config": "{}", METADATA_CHECKSUM_KEY: "x"}) == metadata_digest({"config": "{}"})
    True
    """
    body = {k: v for k, v in metadata.items() if k not in (CHECKSUM_KEY, METADATA_CHECKSUM_KEY)}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def tensors_digest(header: Mapping[str, Any], data: bytes | memoryview) -> str:
    """The hex sha256 of a safetensors file's tensors: for each tensor in name order, its name, dtype and
    shape (as JSON), then its raw bytes.

    ``header`` is the file's parsed JSON header (its ``__metadata__`` is
    skipped) and ``data`` the bytes after it. The digest does not depend on
    the metadata or on where the tensors lie in the file.

    >>> header = {"w": {"dtype": "U8", "shape": [2], "data_offsets": [0, 2]}}
    >>> tensors_digest(header, b"ab")[:16]
    '1a30121a6bb8c155'
    """
    h = hashlib.sha256()
    view = memoryview(data)
    for name in sorted(k for k in header if k != "__metadata__"):
        entry = header[name]
        begin, stop = entry["data_offsets"]
        h.update(json.dumps([name, entry["dtype"], entry["shape"]]).encode() + b"\n")
        h.update(view[begin:stop])
    return h.hexdigest()


def _write(path: Path, header: Mapping[str, Any], data: bytes | memoryview) -> None:
    """Write a safetensors file of ``header`` and ``data`` atomically, the header padded to 8 bytes."""
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    with atomic_open(path, "wb") as fh:
        fh.write(len(text).to_bytes(8, "little"))
        fh.write(text)
        fh.write(data)


def _parse(src: Path) -> tuple[bytes, dict[str, Any], dict[str, Any], memoryview]:
    """``(file bytes, tensor entries, metadata, data)`` of a safetensors file whose header has been checked.

    Checked: size, header length and JSON, each entry's dtype, shape and byte
    range, and that the ranges tile the data. ``CheckpointError`` naming the file otherwise.
    """
    if not src.is_file():
        raise CheckpointError(f"no checkpoint file at {str(src)!r}")
    size = src.stat().st_size
    if size > MAX_CHECKPOINT_BYTES:
        raise CheckpointError(f"{src}: {size} bytes, more than the {MAX_CHECKPOINT_BYTES} a checkpoint may have")
    try:
        raw = src.read_bytes()
    except OSError as err:
        raise CheckpointError(f"{src}: cannot be read ({err})") from None
    if len(raw) < 8:
        raise CheckpointError(f"{src}: {len(raw)} bytes, too short for a safetensors file (truncated?)")
    n = int.from_bytes(raw[:8], "little")
    if n > _MAX_HEADER_BYTES or 8 + n > len(raw):
        raise CheckpointError(
            f"{src}: not a safetensors checkpoint or truncated (header of {n} bytes, file of {len(raw)} bytes)"
        )
    try:
        header = json.loads(raw[8 : 8 + n])
    except (UnicodeDecodeError, ValueError):
        raise CheckpointError(f"{src}: not a safetensors checkpoint (its header is not JSON)") from None
    if not isinstance(header, dict):
        raise CheckpointError(f"{src}: not a safetensors checkpoint (its header is not a JSON object)")
    metadata = header.pop("__metadata__", None)
    if metadata is not None and not isinstance(metadata, dict):
        raise CheckpointError(f"{src}: not a safetensors checkpoint (its __metadata__ is not a JSON object)")
    data = memoryview(raw)[8 + n :]
    spans = []
    for name, entry in header.items():
        spans.append((*_check_entry(src, name, entry, len(data)), name))
    spans.sort()
    end = 0
    for begin, stop, name in spans:
        if begin != end:
            raise CheckpointError(f"{src}: tensor {name!r} starts at byte {begin}, expected {end} (corrupt file)")
        end = stop
    if end != len(data):
        raise CheckpointError(f"{src}: {len(data) - end} bytes after the last tensor (corrupt file)")
    return raw, header, metadata or {}, data


def _stored_digest(src: Path, metadata: Mapping[str, Any], key: str = CHECKSUM_KEY) -> str | None:
    """The checksum ``key`` a file's metadata holds (``None``: written without one)."""
    stored = metadata.get(key)
    if stored is None:
        return None
    if not (isinstance(stored, str) and _HEX_SHA256.fullmatch(stored)):
        raise CheckpointError(f"{src}: its {key!r} metadata is not a sha256 hex digest (corrupt file)")
    return stored


def _check_metadata(src: Path, metadata: Mapping[str, Any], remedy: str) -> None:
    """``CheckpointError`` when the metadata's checksum (if the file has one) does not match it."""
    stored = _stored_digest(src, metadata, METADATA_CHECKSUM_KEY)
    if stored is not None and metadata_digest(metadata) != stored:
        raise CheckpointError(
            f"{src}: damaged: its metadata (config, normalization) does not match the sha256 checksum written "
            f"with it, so the file changed after it was written; {remedy}"
        )


def read_safetensors(
    path: str | os.PathLike[str], meta_key: str, *, remedy: str = _REMEDY
) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """Tensors and the JSON object stored under metadata ``meta_key`` of a checked safetensors file.

    :class:`~steer_envs.io.CheckpointError` (naming the file) for a missing,
    oversized, truncated or corrupt file, a foreign file without ``meta_key``,
    tensors or metadata that do not match the file's checksums (:data:`CHECKSUM_KEY`,
    :data:`METADATA_CHECKSUM_KEY`; the message ends with ``remedy``, what to do about it), and non-finite
    floating-point tensors. A file without a checksum (written before it was
    kept) loads as before.
    """
    src = _source(path)
    raw, header, metadata, data = _parse(src)
    _check_metadata(src, metadata, remedy)
    if not isinstance(metadata.get(meta_key), str):
        raise CheckpointError(f"{src} is not a steer-envs safetensors checkpoint (no {meta_key!r} metadata)")
    try:
        meta = json.loads(metadata[meta_key])
    except ValueError:
        raise CheckpointError(f"{src}: its {meta_key!r} metadata is not JSON") from None
    if not isinstance(meta, dict):
        raise CheckpointError(f"{src} is not a steer-envs safetensors checkpoint ({meta_key!r} is not a JSON object)")
    stored = _stored_digest(src, metadata)
    damaged = stored is not None and tensors_digest(header, data) != stored
    try:
        tensors = st_load(raw)
    except Exception as err:  # safetensors' own error type; the header checks above leave little for it
        raise CheckpointError(f"{src}: safetensors could not read it ({err})") from None
    nonfinite = next(
        (name for name, t in tensors.items() if t.is_floating_point() and not bool(torch.isfinite(t).all())), None
    )
    if damaged:
        seen = f" (tensor {nonfinite!r} now holds NaN or infinite values)" if nonfinite else ""
        raise CheckpointError(
            f"{src}: damaged: its tensors' bytes do not match the sha256 checksum written with them{seen}, so the "
            f"file changed after it was written; {remedy}"
        )
    if nonfinite is not None:
        raise CheckpointError(f"{src}: tensor {nonfinite!r} holds NaN or infinite values")
    return tensors, meta


def add_checksum(path: str | os.PathLike[str]) -> bool:
    """Give a checkpoint (``.safetensors``) or training record (``.json``) written without a checksum its checksum.

    A checkpoint gets :data:`CHECKSUM_KEY` and :data:`METADATA_CHECKSUM_KEY`
    in its header (whichever it lacks), its tensors' bytes staying as they are;
    a record is rewritten by :func:`write_record` with the same content.
    Atomic. Returns ``False`` when the file already has its checksums (which
    are then verified: ``CheckpointError`` on a mismatch). A new checksum
    vouches for the file as it is now: check an old file first.
    """
    src = _source(path)
    if src.suffix == ".json":
        record = read_record(src)
        if RECORD_CHECKSUM_KEY in json.loads(src.read_text(encoding="utf-8")):
            return False
        write_record(src, record)
        return True
    if src.suffix != ".safetensors":
        raise ValueError(f"path must end with .safetensors or .json, got {str(src)!r}")
    _, header, metadata, data = _parse(src)
    _check_metadata(src, metadata, _REMEDY)
    digest = tensors_digest(header, data)
    stored = _stored_digest(src, metadata)
    if stored is not None and stored != digest:
        raise CheckpointError(f"{src}: damaged: its tensors' bytes do not match its sha256 checksum; {_REMEDY}")
    if stored is not None and METADATA_CHECKSUM_KEY in metadata:
        return False
    added = {CHECKSUM_KEY: digest, METADATA_CHECKSUM_KEY: metadata_digest(metadata)}
    _write(src, {"__metadata__": {**metadata, **added}, **header}, data)
    return True


def _check_entry(src: Path, name: str, entry: Any, data_len: int) -> tuple[int, int]:
    """The byte range of one header entry, after checking its dtype, shape and size."""
    if not isinstance(entry, dict) or set(entry) != {"dtype", "shape", "data_offsets"}:
        raise CheckpointError(f"{src}: header entry {name!r} is not a tensor description (corrupt file)")
    dtype, shape, offsets = entry["dtype"], entry["shape"], entry["data_offsets"]
    if dtype not in _DTYPE_BYTES:
        raise CheckpointError(f"{src}: tensor {name!r} has unsupported dtype {dtype!r}")
    if not (isinstance(shape, list) and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape)):
        raise CheckpointError(f"{src}: tensor {name!r} has an invalid shape {shape!r}")
    if not (
        isinstance(offsets, list)
        and len(offsets) == 2
        and all(isinstance(o, int) and not isinstance(o, bool) for o in offsets)
        and 0 <= offsets[0] <= offsets[1]
    ):
        raise CheckpointError(f"{src}: tensor {name!r} has invalid data offsets {offsets!r}")
    begin, stop = offsets
    if stop > data_len:
        raise CheckpointError(
            f"{src}: tensor {name!r} ends at byte {stop} of the data, which has {data_len} bytes (truncated file)"
        )
    if stop - begin != math.prod(shape) * _DTYPE_BYTES[dtype]:
        raise CheckpointError(
            f"{src}: tensor {name!r} of shape {shape} {dtype} does not match its {stop - begin} bytes"
        )
    return begin, stop


def check_parameter_count(expected: int, tensors: Mapping[str, torch.Tensor], source: str) -> None:
    """``expected`` (what a config implies) within :data:`MAX_PARAMETERS` and equal to the numbers in ``tensors``.

    Called before the network is built, so a config claiming a huge network is
    refused without allocating it.
    """
    if expected > MAX_PARAMETERS:
        raise CheckpointError(
            f"{source}: its config implies a network of {expected:,} parameters, more than the {MAX_PARAMETERS:,} "
            "a checkpoint may hold"
        )
    held = sum(t.numel() for t in tensors.values())
    if held != expected:
        raise CheckpointError(
            f"{source}: its config implies {expected:,} weights but the file holds {held:,} "
            "(the config and the tensors do not belong together)"
        )


def check_state(expected: Mapping[str, torch.Tensor], tensors: Mapping[str, torch.Tensor], source: str) -> None:
    """The tensors of a file must be exactly ``expected`` (a network's state dict): names, shapes and dtypes."""
    missing = sorted(set(expected) - set(tensors))
    unexpected = sorted(set(tensors) - set(expected))
    if missing or unexpected:
        parts = []
        if missing:
            parts.append(f"missing {_short(missing)}")
        if unexpected:
            parts.append(f"unexpected {_short(unexpected)}")
        raise CheckpointError(f"{source}: its tensors do not match the network ({'; '.join(parts)})")
    for name, want in expected.items():
        got = tensors[name]
        if tuple(got.shape) != tuple(want.shape):
            raise CheckpointError(
                f"{source}: tensor {name!r} has shape {tuple(got.shape)}, the network expects {tuple(want.shape)}"
            )
        if got.dtype != want.dtype:
            raise CheckpointError(f"{source}: tensor {name!r} has dtype {got.dtype}, the network expects {want.dtype}")


def _short(names: list[str]) -> str:
    return ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")


def write_record(path: str | os.PathLike[str], record: Mapping[str, Any]) -> Path:
    """Write the JSON object ``record`` (indented) with the sha256 of its content under :data:`RECORD_CHECKSUM_KEY`,
    atomically; returns the path.

    The digest covers the record's canonical JSON (sorted keys, no spaces), so
    :func:`read_record` can tell an intact record from one whose bytes changed.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     read_record(write_record(f"{tmp}/r.json", {"steps": 3}))
    {'steps': 3}
    """
    out = _source(path)
    body = {k: v for k, v in record.items() if k != RECORD_CHECKSUM_KEY}
    try:
        body = json.loads(json.dumps(body))  # as a reader will see it (tuples as lists, keys as strings)
    except (TypeError, ValueError) as err:
        raise TypeError(f"the training record must be JSON-serializable ({err})") from None
    atomic_write_text(out, json.dumps({**body, RECORD_CHECKSUM_KEY: _record_digest(body)}, indent=1) + "\n")
    return out


def _record_digest(body: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def read_record(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The JSON object of a checkpoint's training record (without its checksum); ``CheckpointError`` naming the
    file otherwise.

    Refused: a missing file, one larger than :data:`MAX_RECORD_BYTES`, text
    that is not JSON, JSON that is not an object, and a record whose content
    does not match its :data:`RECORD_CHECKSUM_KEY` (changed after
    :func:`write_record` wrote it). A record without a checksum (written
    before it was kept) loads as before.
    """
    src = _source(path)
    if not src.is_file():
        raise CheckpointError(f"no training record at {str(src)!r}")
    if src.stat().st_size > MAX_RECORD_BYTES:
        raise CheckpointError(f"{src}: more than {MAX_RECORD_BYTES} bytes, not a training record")
    try:
        value = json.loads(src.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise CheckpointError(f"{src}: cannot be read as a JSON training record ({err})") from None
    if not isinstance(value, dict):
        raise CheckpointError(f"{src}: a training record is a JSON object, got {type(value).__name__}")
    stored = value.pop(RECORD_CHECKSUM_KEY, None)
    intact = isinstance(stored, str) and _HEX_SHA256.fullmatch(stored) and _record_digest(value) == stored
    if stored is not None and not intact:
        raise CheckpointError(
            f"{src}: damaged or edited: its content does not match the {RECORD_CHECKSUM_KEY!r} checksum written "
            f"with it; restore it from a good copy, or delete the {RECORD_CHECKSUM_KEY!r} entry to accept an edit"
        )
    return value
