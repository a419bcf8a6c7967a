"""steer_envs.io: atomic writes (modes, fsync, stale temp files), atomic folders, checked .npz reading, kills."""

from __future__ import annotations

import io
import os
import stat
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kills import FORK, kill_mid_write

from steer_envs import io as sio
from steer_envs.io import (
    CheckpointError,
    DatasetError,
    atomic_directory,
    atomic_open,
    atomic_write_bytes,
    atomic_write_npz,
    atomic_write_text,
    clean_stale_temps,
    read_npz,
)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# --------------------------------------------------------------------------- writers
def test_errors_are_value_errors() -> None:
    assert issubclass(CheckpointError, ValueError) and issubclass(DatasetError, ValueError)


def test_written_files_get_normal_modes_and_fsync(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    synced: list[int] = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real_fsync(fd))[1])
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a" / "b.txt", "x")
        path = atomic_write_npz(tmp_path / "c.npz", {"x": np.arange(3)})
        with atomic_directory(tmp_path / "folder") as build:
            (build / "f.txt").write_text("y")
    finally:
        os.umask(old)
    assert _mode(tmp_path / "a" / "b.txt") == 0o640  # 0o666 & ~0o027, not mkstemp's 0o600
    assert _mode(path) == 0o640
    assert _mode(tmp_path / "folder") == 0o750  # not mkdtemp's 0o700
    assert len(synced) >= 3 + 3  # each file, and the folder after each rename
    assert _temps(tmp_path) == []


def test_atomic_open_keeps_the_old_file_on_error(tmp_path: Path) -> None:
    target = tmp_path / "t.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError), atomic_open(target, "w") as fh:
        fh.write("new, half")
        raise RuntimeError("boom")
    assert target.read_text() == "old" and _temps(tmp_path) == []


@pytest.mark.parametrize(
    ("path", "exc"),
    [("", ValueError), (3, TypeError), (b"x", TypeError), ("a\x00b", ValueError)],
)
def test_bad_paths_are_refused(path: Any, exc: type[Exception]) -> None:
    with pytest.raises(exc, match="path"):
        atomic_write_text(path, "x")


def test_writing_over_a_folder_or_under_a_file_is_an_os_error(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    with pytest.raises(IsADirectoryError, match="folder"):
        atomic_write_text(tmp_path / "d", "x")
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError):
        atomic_write_text(tmp_path / "f" / "g.txt", "x")
    with pytest.raises(TypeError, match="text"):
        atomic_write_text(tmp_path / "h.txt", b"bytes")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="objects"):
        atomic_write_npz(tmp_path / "o.npz", {"x": np.array([{}], dtype=object)})


def _leftover(folder: Path, name: str, pid: int, age: float = 0.0, *, directory: bool = False) -> Path:
    path = folder / f".{name}.{pid}-abcd1234.tmp"
    if directory:
        path.mkdir()
        (path / "inner").write_text("x")
    else:
        path.write_text("partial")
    if age:
        t = time.time() - age
        os.utime(path, (t, t))
    return path


def _dead_pid() -> int:
    proc = FORK.Process(target=os._exit, args=(0,))
    proc.start()
    proc.join()
    return int(proc.pid)  # type: ignore[arg-type]


def test_stale_temps_of_dead_writers_are_cleaned_at_the_next_write(tmp_path: Path) -> None:
    dead = _dead_pid()
    stale_file = _leftover(tmp_path, "data.npz", dead)
    stale_dir = _leftover(tmp_path, "ds", dead, directory=True)
    reused = _leftover(tmp_path, "x.json", os.getppid(), age=3600)  # live pid but old and unlocked: pid reuse
    fresh_live = _leftover(tmp_path, "y.json", os.getppid())  # a live writer between mkstemp and flock
    legacy_old = tmp_path / ".z.json.abcd1234.tmp"
    legacy_old.write_text("x")
    os.utime(legacy_old, (time.time() - 7200, time.time() - 7200))
    legacy_new = tmp_path / ".w.json.abcd1234.tmp"
    legacy_new.write_text("x")
    foreign = [tmp_path / "notes.tmp", tmp_path / ".keep", tmp_path / f".a.{dead}-abc.tmp"]
    for p in foreign:
        p.write_text("mine")
    atomic_write_text(tmp_path / "other.txt", "x")
    left = set(_temps(tmp_path)) | {p.name for p in tmp_path.iterdir()}
    assert not stale_file.exists() and not stale_dir.exists() and not reused.exists() and not legacy_old.exists()
    assert fresh_live.exists() and legacy_new.exists() and all(p.name in left for p in foreign)


def test_a_locked_temp_file_is_never_cleaned(tmp_path: Path) -> None:
    dead = _dead_pid()
    path = _leftover(tmp_path, "held.txt", dead, age=3600)
    import fcntl

    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # as a writer holds it (or a forked child of one)
        assert clean_stale_temps(tmp_path) == []
        assert path.exists()
    finally:
        os.close(fd)
    assert clean_stale_temps(tmp_path) == [path]


def test_concurrent_writers_do_not_clean_each_other(tmp_path: Path) -> None:
    target = tmp_path / "a.txt"
    with atomic_open(target, "w") as fh:
        fh.write("first")
        atomic_write_text(tmp_path / "b.txt", "second")  # cleans the folder while "a" is being written
        assert len(_temps(tmp_path)) == 1
    assert target.read_text() == "first" and (tmp_path / "b.txt").read_text() == "second"


def test_atomic_directory(tmp_path: Path) -> None:
    target = tmp_path / "ns" / "ds"
    with atomic_directory(target) as build:
        (build / "data").mkdir()
        (build / "data" / "x.bin").write_bytes(b"1")
        assert not target.exists()
    assert (target / "data" / "x.bin").read_bytes() == b"1"
    with pytest.raises(FileExistsError, match="already exists"), atomic_directory(target):
        pass
    with pytest.raises(KeyError), atomic_directory(tmp_path / "failed") as build:
        (build / "half").write_text("x")
        raise KeyError("boom")
    assert not (tmp_path / "failed").exists() and _temps(tmp_path) == []
    with atomic_directory(target, overwrite=True) as build:
        (build / "new").write_text("2")
    assert sorted(p.name for p in target.iterdir()) == ["new"] and _temps(target.parent) == []


# ---------------------------------------------------------------------------- reader
def _npz_bytes(**arrays: Any) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def test_read_npz_round_trip_and_refusals(tmp_path: Path) -> None:
    good = tmp_path / "g.npz"
    atomic_write_npz(good, {"a": np.arange(6.0).reshape(2, 3), "s": np.array("text"), "f": np.ones((2, 3)).T})
    arrays = read_npz(good)
    assert arrays["a"].tolist() == [[0, 1, 2], [3, 4, 5]] and str(arrays["s"]) == "text"
    assert arrays["f"].shape == (3, 2)
    pickled = tmp_path / "p.npz"
    pickled.write_bytes(_npz_bytes(x=np.array([{"a": 1}], dtype=object)))
    with pytest.raises(DatasetError, match=r"p.npz.*pickled objects are never loaded"):
        read_npz(pickled)
    with pytest.raises(DatasetError, match="no such file"):
        read_npz(tmp_path / "missing.npz")
    (tmp_path / "t.npz").write_bytes(good.read_bytes()[:-40])
    with pytest.raises(DatasetError, match=r"t.npz"):
        read_npz(tmp_path / "t.npz")
    (tmp_path / "n.npz").write_text("not a zip")
    with pytest.raises(CheckpointError, match=r"n.npz: not a readable .npz"):
        read_npz(tmp_path / "n.npz", error=CheckpointError)
    with pytest.raises(DatasetError, match="limit"):
        read_npz(good, max_bytes=10)


def test_read_npz_refuses_a_header_claiming_more_than_its_member(tmp_path: Path) -> None:
    """A 51 GB claim in a few bytes is refused before anything is allocated."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10**5, 65536)})
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("x.npy", header.getvalue() + b"\0" * 1000)
    start = time.perf_counter()
    with pytest.raises(DatasetError, match="claims shape"):
        read_npz(path)
    assert time.perf_counter() - start < 1.0


@settings(max_examples=40, deadline=None)
@given(cut=st.integers(0, 10_000), flips=st.lists(st.tuples(st.integers(0, 10_000), st.integers(1, 255)), max_size=4))
def test_read_npz_of_damaged_bytes_reads_or_raises_dataset_error(cut: int, flips: list[tuple[int, int]]) -> None:
    raw = bytearray(_npz_bytes(a=np.arange(50.0), b=np.array("meta"), c=np.zeros((3, 4), dtype=np.int16)))
    for pos, x in flips:
        raw[pos % len(raw)] ^= x
    data = bytes(raw[: len(raw) - cut % len(raw)])
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "d.npz")
        path.write_bytes(data)
        try:
            out = read_npz(path)
        except DatasetError as err:
            assert "d.npz" in str(err)
        else:
            assert all(isinstance(v, np.ndarray) for v in out.values())


# ------------------------------------------------------------------------------ kills
def test_kill_mid_write_leaves_the_old_file_and_the_next_write_cleans_up(tmp_path: Path) -> None:
    target = tmp_path / "r.bin"
    atomic_write_bytes(target, b"old")

    def torn(pause: Callable[[], None]) -> None:  # killed inside the with block: half the new data written
        with atomic_open(target, "wb") as fh:
            fh.write(b"new-" * 1000)
            fh.flush()
            pause()

    kill_mid_write(lambda pause: atomic_write_bytes(target, b"new" * 1000))
    first = _temps(tmp_path)
    assert target.read_bytes() == b"old" and len(first) == 1
    kill_mid_write(torn, at_fsync=False)  # its own start removed the first leftover
    second = _temps(tmp_path)
    assert target.read_bytes() == b"old" and len(second) == 1 and second != first
    atomic_write_bytes(target, b"next")
    assert target.read_bytes() == b"next" and _temps(tmp_path) == []


def test_kill_while_building_a_folder_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "dataset"

    def build(pause: Callable[[], None] | None = None) -> None:
        with atomic_directory(target) as tmp:
            (tmp / "data.bin").write_bytes(b"x" * 1000)

    kill_mid_write(build)
    assert not target.exists() and len(_temps(tmp_path)) == 1
    build()
    assert (target / "data.bin").stat().st_size == 1000 and _temps(tmp_path) == []


def test_io_module_doc_names_the_temp_pattern() -> None:
    assert ".<target name>.<pid>-<8 random chars>.tmp" in (sio.__doc__ or "")
