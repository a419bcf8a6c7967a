"""The results directory of a run: JSON lines appended safely, read tolerantly, resumed.

Layout of ``--out DIR``::

    results.jsonl   one finished trial per line, appended as each trial finishes
    failures.jsonl  trials that raised (they are re-run on resume)
    manifest.json   which suite the directory holds and one entry per session
    discarded.jsonl bytes dropped while repairing (a torn last line), for forensics

Every line is written with one ``os.write`` on an ``O_APPEND`` descriptor and
``fsync``-ed before the next trial is recorded. A writer killed mid-write can
still leave a torn last line; :func:`read_jsonl` ignores it and
:meth:`ResultStore.open` rewrites the file without it (temp file +
``os.replace``) and says so in :attr:`ResultStore.notes`, so a resumed run
appends after the last complete record.
Records are keyed by :attr:`Trial.key`; duplicates are dropped on read.

>>> import tempfile
>>> with tempfile.TemporaryDirectory() as out:
...     with ResultStore(out, suite="selftest") as store:
...         store.append({"key": "k1", "config": {"suite": "selftest"}, "seed": 0, "metrics": {"pi": 3.1}})
...     manifest, records, report = load_results(out)
>>> manifest["suite"], [r["key"] for r in records], report.clean
('selftest', ['k1'], True)
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from steer_envs.io import atomic_write_bytes, atomic_write_text, fsync_dir

RESULTS_FILE = "results.jsonl"
FAILURES_FILE = "failures.jsonl"
MANIFEST_FILE = "manifest.json"
DISCARDED_FILE = "discarded.jsonl"
LOCK_FILE = ".lock"
SCHEMA_VERSION = 1


class StoreLockedError(RuntimeError):
    """Another ``steer-bench run`` is writing to the same directory."""


def utc_now() -> str:
    """Current UTC time, ISO 8601 with seconds.

    >>> utc_now().endswith("+00:00")
    True
    """
    return datetime.now(UTC).isoformat(timespec="seconds")


def encode_record(record: Mapping[str, Any]) -> bytes:
    r"""One JSON line (strict JSON: NaN/inf rejected; newlines inside strings are escaped).

    >>> encode_record({"key": "k", "note": "a\nb"})
    b'{"key":"k","note":"a\\nb"}\n'
    """
    if not isinstance(record, Mapping):
        raise TypeError(f"record must be a mapping, got {type(record).__name__}")
    try:
        text = json.dumps(record, sort_keys=True, allow_nan=False, separators=(",", ":"))
    except ValueError as exc:
        raise ValueError(f"record is not strict JSON (NaN or inf?): {exc}") from None
    return (text + "\n").encode("utf-8")


@dataclass
class ReadReport:
    """What :func:`read_jsonl` had to skip."""

    torn_tail: bytes = b""  # bytes after the last newline (a writer killed mid-line)
    corrupt_lines: list[int] = field(default_factory=list)  # 1-based numbers of unparsable complete lines
    duplicates: int = 0  # records whose key was already seen (first one kept)

    @property
    def clean(self) -> bool:
        return not self.torn_tail and not self.corrupt_lines and not self.duplicates


def read_jsonl(path: str | os.PathLike[str], *, key: str | None = "key") -> tuple[list[dict[str, Any]], ReadReport]:
    r"""Records of a JSON-lines file, tolerating a torn last line.

    Complete lines that do not parse as a JSON object (with ``key``, when
    given) are skipped and listed in the report; with ``key``, later
    duplicates of a key are dropped. A missing file reads as empty.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp) / "r.jsonl"
    ...     _ = path.write_bytes(b'{"key": "a"}\n{"key": "a"}\nnot json\n{"key": "b", "tor')
    ...     records, report = read_jsonl(path)
    >>> [r["key"] for r in records], report.duplicates, report.corrupt_lines, report.torn_tail
    (['a'], 1, [3], b'{"key": "b", "tor')
    """
    path = Path(path)
    report = ReadReport()
    if not path.exists():
        return [], report
    data = path.read_bytes()
    body, sep, tail = data.rpartition(b"\n")
    if not sep:  # no newline at all: everything is a torn line
        body, tail = b"", data
    report.torn_tail = tail
    records: list[dict[str, Any]] = []
    seen: set[str] = set()
    if body or sep:
        for lineno, raw in enumerate(body.split(b"\n"), start=1):
            if not raw.strip():
                continue
            try:
                rec = json.loads(raw)
            except (json.JSONDecodeError, UnicodeDecodeError):
                report.corrupt_lines.append(lineno)
                continue
            if not isinstance(rec, dict) or (key is not None and not isinstance(rec.get(key), str)):
                report.corrupt_lines.append(lineno)
                continue
            if key is not None:
                if rec[key] in seen:
                    report.duplicates += 1
                    continue
                seen.add(rec[key])
            records.append(rec)
    return records, report


class ResultStore:
    """Exclusive, append-only access to one results directory.

    Use as a context manager (it locks the directory; a second writer gets
    :class:`StoreLockedError`):

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as out:
    ...     with ResultStore(out, suite="smoke") as store:
    ...         if "k1" not in store.finished_keys:
    ...             store.append({"key": "k1", "metrics": {}})
    ...     with ResultStore(out, suite="smoke") as resumed:
    ...         sorted(resumed.finished_keys)
    ['k1']
    """

    def __init__(self, out_dir: str | os.PathLike[str], suite: str) -> None:
        if not isinstance(suite, str) or not suite:
            raise ValueError(f"suite must be a non-empty string, got {suite!r}")
        self.out_dir = Path(out_dir)
        self.suite = suite
        self.records: list[dict[str, Any]] = []
        self.notes: list[str] = []
        self._fd: int | None = None
        self._lock_fd: int | None = None

    @property
    def results_path(self) -> Path:
        return self.out_dir / RESULTS_FILE

    @property
    def finished_keys(self) -> set[str]:
        """Keys of the trials already recorded."""
        return {r["key"] for r in self.records}

    # -------------------------------------------------------------- lifecycle
    def open(self) -> ResultStore:
        """Lock the directory, check the manifest, repair a torn tail, load the records."""
        if self.out_dir.exists() and not self.out_dir.is_dir():
            raise ValueError(f"--out {self.out_dir} exists and is not a directory")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._lock()
        try:
            self._check_manifest()
            self._repair_and_load()
            self._fd = os.open(self.results_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            fsync_dir(self.out_dir)
        except BaseException:
            self.close()
            raise
        return self

    def close(self) -> None:
        """Release the file and the lock (idempotent)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # closing releases the flock
            self._lock_fd = None

    def __enter__(self) -> ResultStore:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _lock(self) -> None:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - non-POSIX: no inter-process lock
            return
        fd = os.open(self.out_dir / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StoreLockedError(f"another steer-bench run is writing to {self.out_dir}") from None
        self._lock_fd = fd

    def _check_manifest(self) -> None:
        path = self.out_dir / MANIFEST_FILE
        if path.exists():
            try:
                manifest = json.loads(path.read_text())
            except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                raise ValueError(f"{path} is not valid JSON ({exc}); is --out a steer-bench directory?") from None
            if manifest.get("suite") != self.suite:
                raise ValueError(
                    f"{self.out_dir} holds results of suite {manifest.get('suite')!r}, not {self.suite!r}; "
                    "choose another --out"
                )
        elif any(self.out_dir.glob("*.jsonl")):
            raise ValueError(f"{self.out_dir} has JSON lines but no {MANIFEST_FILE}; not a steer-bench directory")
        else:
            manifest = {"schema": SCHEMA_VERSION, "suite": self.suite, "created": utc_now(), "sessions": []}
            atomic_write_text(path, json.dumps(manifest, indent=2, sort_keys=True) + "\n")

    def _repair_and_load(self) -> None:
        self.records, report = read_jsonl(self.results_path)
        if report.clean:
            return
        discarded: list[dict[str, Any]] = []
        if report.torn_tail:
            discarded.append(
                {"at": utc_now(), "reason": "torn last line", "bytes": report.torn_tail.decode("utf-8", "replace")}
            )
            self.notes.append(f"dropped a torn last line ({len(report.torn_tail)} bytes) from {RESULTS_FILE}")
        if report.corrupt_lines:
            lines = self.results_path.read_bytes().split(b"\n")
            for n in report.corrupt_lines:
                discarded.append(
                    {"at": utc_now(), "reason": f"corrupt line {n}", "bytes": lines[n - 1].decode("utf-8", "replace")}
                )
            self.notes.append(f"dropped corrupt lines {report.corrupt_lines} from {RESULTS_FILE}")
        if report.duplicates:
            self.notes.append(f"dropped {report.duplicates} duplicate records from {RESULTS_FILE}")
        for item in discarded:
            _append_line(self.out_dir / DISCARDED_FILE, encode_record(item))
        atomic_write_bytes(self.results_path, b"".join(encode_record(r) for r in self.records))

    # ---------------------------------------------------------------- writing
    def append(self, record: Mapping[str, Any]) -> None:
        """Append one finished trial (flushed and fsync-ed before returning)."""
        if self._fd is None:
            raise RuntimeError("ResultStore is not open")
        if not isinstance(record.get("key"), str):
            raise ValueError("record must carry a string 'key'")
        if record["key"] in self.finished_keys:
            raise ValueError(f"trial {record['key']} is already recorded in {self.results_path}")
        data = encode_record(record)
        _write_all(self._fd, data)
        os.fsync(self._fd)
        self.records.append(dict(record))

    def append_failure(self, record: Mapping[str, Any]) -> None:
        """Log a failed trial to ``failures.jsonl`` (informational; the trial is re-run on resume)."""
        _append_line(self.out_dir / FAILURES_FILE, encode_record(record))

    def start_session(self, info: Mapping[str, Any]) -> None:
        """Record one ``run`` invocation in ``manifest.json`` (atomic rewrite)."""
        if self._fd is None:
            raise RuntimeError("ResultStore is not open")
        path = self.out_dir / MANIFEST_FILE
        manifest = json.loads(path.read_text())
        manifest.setdefault("sessions", []).append({"started": utc_now(), **dict(info)})
        atomic_write_text(path, json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def _append_line(path: Path, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        _write_all(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


def load_results(out_dir: str | os.PathLike[str]) -> tuple[dict[str, Any], list[dict[str, Any]], ReadReport]:
    """Manifest and records of a results directory, read-only (no lock, no repair).

    ``FileNotFoundError`` when ``out_dir`` is not a steer-bench directory.

    >>> load_results("/nonexistent/steer-bench-dir")
    Traceback (most recent call last):
    FileNotFoundError: no results directory at /nonexistent/steer-bench-dir
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"no results directory at {out_dir}")
    manifest_path = out_dir / MANIFEST_FILE
    if not manifest_path.exists():
        raise FileNotFoundError(f"{out_dir} has no {MANIFEST_FILE}; is it a steer-bench --out directory?")
    manifest = json.loads(manifest_path.read_text())
    records, report = read_jsonl(out_dir / RESULTS_FILE)
    return manifest, records, report
