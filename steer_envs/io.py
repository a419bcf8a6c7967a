"""Atomic file writing, safe ``.npz`` reading, and the errors raised for unreadable checkpoint and dataset files.

Every module that writes results, datasets, checkpoints or figures goes
through here, so a reader never sees a half-written file and a crash (even a
``kill -9``) never loses the previous version:

* a file is written to a temp file in the target's folder, flushed and
  ``fsync``'d, given the usual permissions (``0o666 & ~umask``, not
  ``mkstemp``'s 0600), renamed over the target with ``os.replace``, and the
  folder is ``fsync``'d so the rename survives a power cut
  (:func:`atomic_open`, :func:`atomic_write_bytes`, :func:`atomic_write_text`,
  :func:`atomic_write_npz`);
* a multi-file output (a Minari dataset) is built in a temp folder next to
  the target and renamed into place (:func:`atomic_directory`);
* temp names are ``.<target name>.<pid>-<8 random chars>.tmp``; a writer
  holds an ``flock`` on its temp file (or folder) while it writes. Leftovers
  of killed writers are removed at the next write to the same folder
  (:func:`clean_stale_temps`): only names of that pattern whose lock is free
  and whose writer process is gone (or that are older than
  :data:`STALE_AFTER_S`, for a reused process id).

Reading: :func:`read_npz` loads an ``.npz`` archive without pickle and checks
every array's header (dtype, shape, size) before allocating it, then the
CRC-32 checksum the zip format stores for every member (so a file whose bytes
changed after it was written is refused).
:class:`CheckpointError` and :class:`DatasetError` are the one error type of
each kind of file (both are ``ValueError``\\ s); their message names the file
and what is wrong.

>>> import tempfile
>>> from pathlib import Path
>>> with tempfile.TemporaryDirectory() as tmp:
...     path = Path(tmp, "results", "trial.json")
...     atomic_write_text(path, '{"success": true}')
...     with atomic_open(path, "w") as fh:
...         _ = fh.write('{"success": false}')
...     print(path.read_text(), sorted(p.name for p in path.parent.iterdir()))
{"success": false} ['trial.json']
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import shutil
import stat
import tempfile
import time
import zipfile
import zlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

import numpy as np

try:  # POSIX advisory locks; elsewhere only the process-id rule applies
    import fcntl
except ImportError:  # pragma: no cover - not on Linux / macOS
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "CACHE_ENV",
    "MAX_NPZ_BYTES",
    "STALE_AFTER_S",
    "CheckpointError",
    "DatasetError",
    "atomic_directory",
    "atomic_open",
    "atomic_write_bytes",
    "atomic_write_npz",
    "atomic_write_text",
    "clean_stale_temps",
    "default_cache_dir",
    "file_sha256",
    "fsync_dir",
    "npz_json",
    "read_npz",
    "require_arrays",
]


#: the environment variable whose folder holds every cache (``~/.cache`` when unset or empty)
CACHE_ENV = "XDG_CACHE_HOME"


def default_cache_dir(name: str) -> Path:
    """``$XDG_CACHE_HOME/steer-envs/<name>`` (``~/.cache/steer-envs/<name>`` when the variable is unset or empty).

    ``name``: one folder name (a suite's, e.g. ``"itps-blockstack"``).

    Every cache of the library lives there: the shards of the studies, the
    SB3 runs, the converted Kitchen assets.

    >>> default_cache_dir("itps-kitchen").parts[-2:]
    ('steer-envs', 'itps-kitchen')
    """
    if not isinstance(name, str) or not name or name in (".", "..") or "/" in name or os.sep in name:
        raise ValueError(f"default_cache_dir: `name` must be one folder name, got {name!r}")
    root = os.environ.get(CACHE_ENV) or str(Path.home() / ".cache")
    return Path(root) / "steer-envs" / name


class CheckpointError(ValueError):
    """A checkpoint file (or its training record) that cannot be loaded; the message names the file and why.

    Raised before any network is built for: a missing or truncated file, a
    file that is not a safetensors checkpoint of this library, a header or
    config that is malformed or implies an unreasonably large network, tensors
    whose names, shapes or dtypes differ from the network's, tensors whose
    bytes do not match the checksum written with them, and NaN or infinite
    weights.
    """


class DatasetError(ValueError):
    """A dataset file that cannot be loaded; the message names the file and why.

    Raised for a missing file, a file that is not an ``.npz`` archive (or holds
    pickled objects), bytes that do not match the archive's CRC-32
    checksums, a foreign or malformed header, missing arrays, arrays of the
    wrong dtype or shape, sizes beyond :data:`MAX_NPZ_BYTES`, and non-finite
    values where the data must be finite.
    """


#: a temp file or folder whose lock is free and whose writer's process id is alive is still taken for
#: a reused process id (so a leftover) once it is older than this many seconds
STALE_AFTER_S = 30.0
#: leftovers of the earlier temp-name pattern (``.<name>.<8 chars>.tmp``, no process id, no lock) are
#: removed once older than this many seconds
_LEGACY_STALE_AFTER_S = 600.0
_TEMP_RE = re.compile(r"^\..+\.(?P<pid>\d{1,10})-[a-z0-9_]{8}\.tmp$")
_LEGACY_TEMP_RE = re.compile(r"^\..+\.[a-z0-9_]{8}\.tmp$")
#: the largest total of array bytes :func:`read_npz` allocates for one archive (4 GiB)
MAX_NPZ_BYTES = 4 * 2**30
_MAX_NPZ_MEMBERS = 1024
#: deflate cannot compress by more than about 1032:1, so a member that claims more is corrupt
_DEFLATE_MAX_RATIO = 1100


# --------------------------------------------------------------------------- helpers
def _target(path: Any, what: str = "path") -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{what} must be a str or os.PathLike, got {type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        raise TypeError(f"{what} must be a str path, got bytes")
    if text == "":
        raise ValueError(f"{what} must not be empty")
    if "\x00" in text:
        raise ValueError(f"{what} must not contain NUL characters")
    return Path(text)


def _umask() -> int:
    """The process umask, read without changing it where Linux allows (``os.umask`` is process-global)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _temp_prefix(name: str) -> str:
    return f".{name[:160]}.{os.getpid()}-"


def _try_lock(fd: int) -> bool | None:
    """Take an exclusive non-blocking ``flock`` on ``fd``: True taken, False held elsewhere, None unsupported."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:
        return None
    return True


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, another user's
        return True
    except OverflowError:
        return False
    try:  # a killed child its parent has not reaped yet is a zombie: gone for our purposes
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            state = fh.read().rsplit(")", 1)[-1].split()[0]
        return state not in ("Z", "X")
    except (OSError, IndexError):
        return True


def _makedirs(directory: Path) -> None:
    """Create ``directory`` and its missing parents, each with an ``fsync`` of the folder that holds it."""
    if directory.is_dir():
        return
    missing = []
    d = directory
    while not d.exists() and not d.is_symlink():
        missing.append(d)
        if d.parent == d:
            break
        d = d.parent
    if not missing and not directory.is_dir():
        raise NotADirectoryError(f"{directory} exists and is not a folder")
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            if not d.is_dir():
                raise NotADirectoryError(f"{d} exists and is not a folder") from None
        fsync_dir(d.parent)


def fsync_dir(directory: str | os.PathLike[str]) -> None:
    """Flush a directory entry (after a rename) where the platform allows it."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove(path: Path, is_dir: bool) -> None:
    if is_dir:
        shutil.rmtree(path, ignore_errors=True)
    else:
        with suppress(FileNotFoundError):
            path.unlink()


def clean_stale_temps(directory: str | os.PathLike[str]) -> list[Path]:
    """Remove the leftovers of killed writers in ``directory``; returns what was removed.

    Only names of this module's temp pattern (``.<name>.<pid>-<8 chars>.tmp``,
    files or folders) are considered, and of those only the ones whose lock is
    free and whose writer process has exited, or, for a reused process id,
    that are older than :data:`STALE_AFTER_S`. Leftovers of the earlier
    pattern (``.<name>.<8 chars>.tmp``) go once older than ten minutes.
    Never raises: a folder that cannot be listed is left alone.
    """
    folder = Path(directory)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        name = entry.name
        if not (name.startswith(".") and name.endswith(".tmp")):
            continue
        match = _TEMP_RE.match(name)
        if match is None and _LEGACY_TEMP_RE.match(name) is None:
            continue
        try:
            st = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        is_dir = stat.S_ISDIR(st.st_mode)
        if not (is_dir or stat.S_ISREG(st.st_mode)):
            continue
        path = folder / name
        flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | (getattr(os, "O_DIRECTORY", 0) if is_dir else 0)
        try:
            fd = os.open(path, flags)
        except OSError:
            continue
        try:
            if _try_lock(fd) is False:  # its writer is still at work
                continue
            age = now - st.st_mtime
            if match is not None:
                stale = not _pid_alive(int(match["pid"])) or age > STALE_AFTER_S
            else:
                stale = age > _LEGACY_STALE_AFTER_S
            if stale:
                _remove(path, is_dir)
                removed.append(path)
        finally:
            os.close(fd)
    return removed


# ---------------------------------------------------------------------------- writers
@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temp file that replaces ``path`` when the block exits without error.

    ``mode`` is ``"wb"`` or ``"w"`` (UTF-8 text). On an exception the temp file
    is removed and ``path`` is left untouched. The new file gets the usual
    permissions (``0o666 & ~umask``); missing parent folders are created.
    Stale temp files of killed writers in the folder are removed first
    (:func:`clean_stale_temps`).
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    target = _target(path)
    if target.is_dir():
        raise IsADirectoryError(f"cannot write the file {str(target)!r}: it is a folder")
    parent = target.parent
    _makedirs(parent)
    clean_stale_temps(parent)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(target.name), suffix=".tmp", dir=parent)
    try:
        _try_lock(fd)  # held until the file is closed, i.e. after the rename
        with os.fdopen(fd, mode, encoding="utf-8" if mode == "w" else None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
            os.replace(tmp, target)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    fsync_dir(parent)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"data must be bytes, got {type(data).__name__}")
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__}")
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_npz(path: str | os.PathLike[str], arrays: Mapping[str, Any], *, compressed: bool = True) -> Path:
    """Write ``arrays`` (name -> array) as an ``.npz`` archive atomically; returns the path.

    Object arrays are refused (they would be pickled, and :func:`read_npz`
    never loads a pickle).

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     read_npz(atomic_write_npz(f"{tmp}/a.npz", {"x": np.arange(3)}))["x"].tolist()
    [0, 1, 2]
    """
    target = _target(path)
    prepared = {}
    for name, value in arrays.items():
        arr = np.asarray(value)
        if arr.dtype.hasobject:
            raise TypeError(f"array {name!r} holds Python objects ({arr.dtype}); only plain arrays are written")
        prepared[str(name)] = arr
    with atomic_open(target, "wb") as fh:
        (np.savez_compressed if compressed else np.savez)(fh, **prepared)  # type: ignore[operator]
    return target


def _fsync_tree(root: Path) -> None:
    for folder, _, files in os.walk(root):
        for name in files:
            fd = os.open(os.path.join(folder, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        fsync_dir(folder)


@contextmanager
def atomic_directory(path: str | os.PathLike[str], *, overwrite: bool = False) -> Iterator[Path]:
    """Build a folder that appears at ``path`` complete or not at all.

    Yields an empty temp folder next to ``path``; when the block exits without
    error, every file in it is ``fsync``'d and the folder is renamed to
    ``path``. On an exception (or a kill) ``path`` is untouched and the temp
    folder is removed (by the next write to the same folder, after a kill).
    An existing ``path`` is ``FileExistsError`` unless ``overwrite``: then an
    existing *folder* is moved aside and removed once the new one is in place
    (a crash in between leaves no folder at ``path``, never a mixed one).
    """
    target = _target(path)
    parent = target.parent
    _makedirs(parent)
    clean_stale_temps(parent)
    if (target.exists() or target.is_symlink()) and not (overwrite and target.is_dir() and not target.is_symlink()):
        raise FileExistsError(f"{str(target)!r} already exists" + ("" if overwrite else " (overwrite=False)"))
    tmp = Path(tempfile.mkdtemp(prefix=_temp_prefix(target.name), suffix=".tmp", dir=parent))
    lock_fd = os.open(tmp, os.O_RDONLY)
    try:
        _try_lock(lock_fd)
        os.chmod(tmp, 0o777 & ~_umask())
        yield tmp
        _fsync_tree(tmp)
        if target.exists() or target.is_symlink():
            if not (overwrite and target.is_dir() and not target.is_symlink()):
                raise FileExistsError(f"{str(target)!r} appeared while it was being built")
            trash = Path(tempfile.mkdtemp(prefix=_temp_prefix(target.name), suffix=".tmp", dir=parent))
            os.rename(target, trash)  # replaces the empty trash folder
            os.rename(tmp, target)
            fsync_dir(parent)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.rename(tmp, target)
        fsync_dir(parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        os.close(lock_fd)


# ---------------------------------------------------------------------------- readers
def file_sha256(path: str | os.PathLike[str]) -> str:
    """The hex sha256 of a file's bytes, read in 1 MiB pieces: the checksum a sidecar records for a file.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     atomic_write_bytes(f"{tmp}/a.bin", b"abc")
    ...     file_sha256(f"{tmp}/a.bin")[:16]
    'ba7816bf8f01cfea'
    """
    digest = hashlib.sha256()
    with open(_target(path), "rb") as fh:
        while chunk := fh.read(2**20):
            digest.update(chunk)
    return digest.hexdigest()


def _read_exact(fh: IO[bytes], n: int) -> bytearray:
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = fh.readinto(view[got:])  # type: ignore[attr-defined]
        if not k:
            raise EOFError(f"expected {n} bytes, got {got}")
        got += k
    return buf


def read_npz(
    path: str | os.PathLike[str],
    *,
    error: type[ValueError] = DatasetError,
    max_bytes: int = MAX_NPZ_BYTES,
) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` archive, each checked from its header before it is allocated; no pickle.

    Refused with ``error`` (naming the file): a missing file, a file that is
    not a zip archive of ``.npy`` arrays, object or structured arrays (which
    would need pickle), headers that claim more data than the member can hold
    (a corrupt or crafted file), archives whose arrays total more than
    ``max_bytes``, truncated or corrupt data, and members whose bytes do
    not match their CRC-32 checksum (damaged after they were written).
    """
    src = _target(path)
    if not src.is_file():
        raise error(f"{src}: no such file")
    arrays: dict[str, np.ndarray] = {}
    total = 0
    name = ""
    try:
        with zipfile.ZipFile(src) as archive:
            members = archive.infolist()
            if len(members) > _MAX_NPZ_MEMBERS:
                raise error(f"{src}: {len(members)} archive members, more than {_MAX_NPZ_MEMBERS}")
            for info in members:
                if not info.filename.endswith(".npy"):
                    raise error(f"{src}: member {info.filename!r} is not a .npy array")
                name = info.filename[: -len(".npy")]
                with archive.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
                    elif version == (2, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
                    else:
                        raise error(f"{src}: array {name!r} has unsupported .npy version {version}")
                    if dtype.hasobject or dtype.fields is not None or dtype.kind == "V":
                        raise error(f"{src}: array {name!r} holds {dtype} data (pickled objects are never loaded)")
                    count = math.prod(shape)
                    nbytes = count * dtype.itemsize
                    limit = info.compress_size * (_DEFLATE_MAX_RATIO if info.compress_type else 1) + 4096
                    if nbytes > limit or nbytes > info.file_size:
                        raise error(
                            f"{src}: array {name!r} claims shape {shape} ({nbytes} bytes) but its archive "
                            f"member holds {info.file_size} bytes (corrupt or truncated)"
                        )
                    total += nbytes
                    if total > max_bytes:
                        raise error(f"{src}: arrays total more than {max_bytes} bytes (the limit)")
                    buf = _read_exact(fh, nbytes)
                    if fh.read(1):  # reading to the member's end also makes zipfile check its CRC-32
                        raise error(f"{src}: array {name!r} is followed by stray bytes in its member (corrupt file)")
                arr = np.frombuffer(buf, dtype=dtype, count=count)
                arrays[name] = arr.reshape(shape[::-1]).T if fortran else arr.reshape(shape)
    except error:
        raise
    except zipfile.BadZipFile as err:
        if not str(err).startswith("Bad CRC-32"):  # zipfile's words for a member whose bytes changed
            raise error(f"{src}: not a readable .npz archive (BadZipFile: {err})") from None
        raise error(
            f"{src}: damaged: array {name!r} does not match the CRC-32 checksum written with it, so the file "
            "changed after it was written; write it again or restore it from a good copy (a cached shard is "
            "rebuilt once it is deleted)"
        ) from None
    except (zlib.error, EOFError, OSError, ValueError, NotImplementedError, KeyError) as err:
        raise error(f"{src}: not a readable .npz archive ({type(err).__name__}: {err})") from None
    return arrays


def require_arrays(
    src: str | os.PathLike[str],
    arrays: Mapping[str, np.ndarray],
    specs: Mapping[str, tuple[str, int]],
    *,
    finite: bool = False,
) -> None:
    """``DatasetError`` naming ``src`` unless each array of ``specs`` (name -> (dtype kinds, axes)) is present and fits.

    ``finite=True`` also refuses NaN/inf in the floating arrays.

    >>> require_arrays("d.npz", {"x": np.zeros((2, 3))}, {"x": ("f", 2)})
    >>> require_arrays("d.npz", {"x": np.zeros(2)}, {"x": ("f", 2)})
    Traceback (most recent call last):
    steer_envs.io.DatasetError: d.npz: array 'x' has dtype float64 and shape (2,), expected dtype kind 'f' and 2 axes
    """
    missing = sorted(set(specs) - set(arrays))
    if missing:
        raise DatasetError(f"{src}: missing arrays {missing}")
    for name, (kinds, ndim) in specs.items():
        arr = arrays[name]
        if arr.dtype.kind not in kinds or arr.ndim != ndim:
            raise DatasetError(
                f"{src}: array {name!r} has dtype {arr.dtype} and shape {arr.shape}, "
                f"expected dtype kind {kinds!r} and {ndim} axes"
            )
        if finite and arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
            raise DatasetError(f"{src}: array {name!r} holds NaN or infinite values")


def npz_json(src: str | os.PathLike[str], arrays: Mapping[str, np.ndarray], key: str) -> dict[str, Any]:
    """The JSON object stored in an ``.npz`` as the 0-d string array ``key`` (``DatasetError`` naming ``src``).

    >>> npz_json("d.npz", {"meta": np.array('{"format": 1}')}, "meta")
    {'format': 1}
    """
    if key not in arrays:
        raise DatasetError(f"{src}: missing arrays [{key!r}]")
    arr = arrays[key]
    if arr.dtype.kind != "U" or arr.ndim != 0:
        raise DatasetError(f"{src}: {key!r} must be a JSON string, got dtype {arr.dtype} shape {arr.shape}")
    try:
        value = json.loads(str(arr))
    except ValueError as err:
        raise DatasetError(f"{src}: {key!r} is not JSON ({err})") from None
    if not isinstance(value, dict):
        raise DatasetError(f"{src}: {key!r} must be a JSON object, got {type(value).__name__}")
    return value
