"""The results directory of a run: JSON lines appended safely, read tolerantly, resumed.

Layout of ``--out DIR``::

    results.jsonl   one finished trial per line, appended as each trial finishes
    failures.jsonl  trials that raised (they are re-run on resume)
    manifest.json   which suite the directory holds and one entry per session
    discarded.jsonl the quarantine: every line moved out of results.jsonl while repairing it, with the reason
    summary.md      the last run's table (written by ``steer-bench run``)
    plots/          the figures of ``steer-bench report --plots`` (its default ``--plots-dir``)
    previous/       earlier results that ``run --fresh`` moved aside, one ``previous/<UTC time>/`` each

``steer-bench run --fresh`` (``ResultStore(..., fresh=True)``) starts a
directory over without deleting anything: under the lock, ``results.jsonl``,
``failures.jsonl``, ``discarded.jsonl``, ``summary.md``, ``plots/`` and
``manifest.json`` (last) move into ``previous/<UTC time>/``, a steer-bench
directory of its own (``steer-bench report DIR/previous/<UTC time>`` reads
it), and the run starts from an empty ``results.jsonl``. Any other file stays
where it is. A directory of another suite, or with JSON lines but no
manifest, is refused as it is without ``--fresh``.

Every line is written with one ``os.write`` on an ``O_APPEND`` descriptor and
``fsync``-ed before the next trial is recorded, so the good lines of
``results.jsonl`` are never rewritten in place. A line that is not a valid
record of this directory (a torn last line of a killed writer, garbage,
valid JSON that is not a record: wrong types, missing fields, a key that does
not match its config, a foreign suite, a duplicate key) is skipped by every
reader, and :meth:`ResultStore.open` (the start of ``steer-bench run``) moves
it to ``discarded.jsonl`` with the reason, rewrites ``results.jsonl`` with the
good lines byte for byte (temp file + ``os.replace``) and says so in
:attr:`ResultStore.notes`. A valid last line that misses only its newline is a
finished trial: it is kept and the newline appended. A resumed run therefore
appends after the last good record, and no finished trial is run twice.

>>> import tempfile
>>> from steer_envs.bench.suite import Trial
>>> trial = Trial("selftest", None, "mc", 0, {}, "math:sqrt")
>>> record = {"key": trial.key, "config": trial.config, "seed": 0, "metrics": {"pi": 3.1}}
>>> with tempfile.TemporaryDirectory() as out:
...     with ResultStore(out, suite="selftest") as store:
...         store.append(record)
...     with open(Path(out) / RESULTS_FILE, "ab") as fh:  # a line that is JSON but no record
...         _ = fh.write(b'{"key": "x"}\\n')
...     manifest, records, report = load_results(out)
...     with ResultStore(out, suite="selftest") as store:  # quarantines the bad line
...         notes = store.notes
>>> manifest["suite"], [r["key"] for r in records] == [trial.key], report.corrupt_lines
('selftest', True, [2])
>>> notes
["quarantined 1 line of results.jsonl in discarded.jsonl: line 2: 'config' is missing"]
"""

from __future__ import annotations

import base64
import json
import os
import stat
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from steer_envs.bench.records import (
    RESULTS_FILE,
    SCHEMA_VERSION,
    ReadReport,
    ResultsDirError,
    count_lines,
    encode_record,
    name_lines,
    parse_json_line,
    read_jsonl,
    read_regular_file,
    record_problem,
    require_regular_file,
    scan_jsonl,
    utc_now,
)
from steer_envs.bench.suite import get_suite, trial_key
from steer_envs.core.validation import describe
from steer_envs.io import atomic_write_bytes, atomic_write_text, fsync_dir

__all__ = [
    "DISCARDED_FILE",
    "FAILURES_FILE",
    "MANIFEST_FILE",
    "PLOTS_DIR",
    "PREVIOUS_DIR",
    "RESULTS_FILE",
    "SUMMARY_FILE",
    "ResultStore",
    "StoreLockedError",
    "atomic_write_text",
    "check_output_dir",
    "load_results",
    "trial_key",
]

FAILURES_FILE = "failures.jsonl"
MANIFEST_FILE = "manifest.json"
DISCARDED_FILE = "discarded.jsonl"
SUMMARY_FILE = "summary.md"
LOCK_FILE = ".lock"
PLOTS_DIR = "plots"
PREVIOUS_DIR = "previous"
#: files of a results directory that must be regular files when they exist
_DIR_FILES = (RESULTS_FILE, FAILURES_FILE, MANIFEST_FILE, DISCARDED_FILE, SUMMARY_FILE, LOCK_FILE)
#: what ``--fresh`` moves aside: everything steer-bench writes into a directory but the lock (the manifest last,
#: so a move cut short leaves a directory that is still resumable, never JSON lines without a manifest)
_FRESH_ITEMS = (RESULTS_FILE, FAILURES_FILE, DISCARDED_FILE, SUMMARY_FILE, PLOTS_DIR, MANIFEST_FILE)


class StoreLockedError(RuntimeError):
    """Another ``steer-bench run`` is writing to the same directory."""


def _read_manifest(path: Path) -> dict[str, Any]:
    data = read_regular_file(path)
    value, reason = parse_json_line(data)
    if reason is not None:
        raise ResultsDirError(f"{path} is {reason}; is this a steer-bench --out directory?")
    if not isinstance(value, dict) or not isinstance(value.get("suite"), str) or not value["suite"]:
        got = "no 'suite'" if isinstance(value, dict) else f"a JSON {type(value).__name__}"
        raise ResultsDirError(
            f"{path} is not a steer-bench manifest (a JSON object with a 'suite' name), got {got}; "
            "is this a steer-bench --out directory?"
        )
    if "sessions" in value and not isinstance(value["sessions"], list):
        raise ResultsDirError(f"{path}: 'sessions' must be a list, got {describe(value['sessions'])}")
    if "schema" in value and value["schema"] != SCHEMA_VERSION:
        raise ResultsDirError(f"{path}: schema {value['schema']!r} is not {SCHEMA_VERSION} (another steer-bench?)")
    return value


def check_output_dir(path: str | os.PathLike[str], what: str = "--out") -> Path:
    """``path`` as a :class:`Path` if it is, or can become, a folder (nothing is created).

    ``TypeError`` for a non-path, :class:`ResultsDirError` for an empty path,
    a path that is a file or lies under one, and an existing folder that
    cannot be written; ``what`` names the option in the message.

    >>> check_output_dir("")
    Traceback (most recent call last):
    steer_envs.bench.records.ResultsDirError: --out must not be empty (it would write into the current folder)
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{what} must be a str or os.PathLike path, got {describe(path)}")
    text = os.fspath(path)
    if not isinstance(text, str):
        raise TypeError(f"{what} must be a str path, got bytes")
    if not text.strip():
        raise ResultsDirError(f"{what} must not be empty (it would write into the current folder)")
    if "\x00" in text:
        raise ResultsDirError(f"{what} must not contain NUL characters")
    target = Path(text)
    probe = target
    while True:
        try:
            mode = os.stat(probe).st_mode
        except (FileNotFoundError, NotADirectoryError):  # missing, or a parent is a file: look further up
            if probe.parent == probe:
                break
            probe = probe.parent
            continue
        except OSError as exc:
            raise ResultsDirError(f"{what} {target}: cannot use {probe} ({exc.strerror or exc})") from None
        if not stat.S_ISDIR(mode):
            where = "exists and is not a folder" if probe == target else f"lies under {probe}, which is not a folder"
            raise ResultsDirError(f"{what} {target} {where}")
        if not os.access(probe, os.W_OK | os.X_OK):
            raise ResultsDirError(f"{what} {target}: {probe} is not writable")
        break
    return target


class ResultStore:
    """Exclusive, append-only access to one results directory.

    Use as a context manager (it locks the directory; a second writer gets
    :class:`StoreLockedError`; an unusable directory :class:`ResultsDirError`).
    ``accepts_suite`` says which ``config.suite`` a record may carry (default:
    only ``suite``; a tour such as ``quick`` holds records of other suites).
    ``fresh=True`` starts the directory over: its earlier results move to
    ``previous/<UTC time>/`` when it is opened (see the module docstring;
    :attr:`notes` says where).

    >>> import tempfile
    >>> from steer_envs.bench.suite import Trial
    >>> trial = Trial("smoke", "steer_envs/ConvexMode-v0", "expert", 0, {}, "math:sqrt")
    >>> with tempfile.TemporaryDirectory() as out:
    ...     with ResultStore(out, suite="smoke") as store:
    ...         if trial.key not in store.finished_keys:
    ...             store.append({"key": trial.key, "config": trial.config, "seed": 0, "metrics": {}})
    ...     with ResultStore(out, suite="smoke") as resumed:
    ...         resumed.finished_keys == {trial.key}
    True
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        suite: str,
        *,
        accepts_suite: Callable[[str], bool] | None = None,
        fresh: bool = False,
    ) -> None:
        if not isinstance(suite, str) or not suite:
            raise ValueError(f"suite must be a non-empty string, got {suite!r}")
        if accepts_suite is not None and not callable(accepts_suite):
            raise TypeError(f"accepts_suite must be a function str -> bool, got {describe(accepts_suite)}")
        if not isinstance(fresh, bool):
            raise TypeError(f"fresh must be a bool, got {describe(fresh)}")
        self.out_dir = check_output_dir(out_dir)
        self.suite = suite
        self.fresh = fresh
        self.previous: Path | None = None  # where fresh=True moved the earlier results (None: nothing moved)
        self.accepts_suite: Callable[[str], bool] = accepts_suite or suite.__eq__
        self.records: list[dict[str, Any]] = []
        self.notes: list[str] = []
        self._keys: set[str] = set()
        self._manifest: dict[str, Any] = {}
        self._fd: int | None = None
        self._lock_fd: int | None = None

    @property
    def results_path(self) -> Path:
        return self.out_dir / RESULTS_FILE

    @property
    def finished_keys(self) -> set[str]:
        """Keys of the trials already recorded."""
        return set(self._keys)

    def problem(self, record: Any) -> str | None:
        """What makes ``record`` not a valid record of this directory (``None`` when it is one)."""
        return record_problem(record, accepts_suite=self.accepts_suite)

    # -------------------------------------------------------------- lifecycle
    def open(self) -> ResultStore:
        """Lock the directory, check the manifest, quarantine bad lines, load the records."""
        check_output_dir(self.out_dir)
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ResultsDirError(f"--out {self.out_dir}: cannot create it ({exc.strerror or exc})") from None
        for name in _DIR_FILES:
            require_regular_file(self.out_dir / name)
        self._lock()
        try:
            if self.fresh:
                self._start_over()
            self._check_manifest()
            self._repair_and_load()
            self._fd = _open_append(self.results_path)
        except OSError as exc:
            self.close()
            raise ResultsDirError(f"--out {self.out_dir}: {exc.strerror or exc} ({exc.filename or ''})") from None
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
        try:
            fd = _open_append(self.out_dir / LOCK_FILE, write=False)
        except OSError as exc:
            raise ResultsDirError(f"--out {self.out_dir}: cannot create {LOCK_FILE} ({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StoreLockedError(f"another steer-bench run is writing to {self.out_dir}") from None
        self._lock_fd = fd

    def _own_manifest(self, path: Path) -> dict[str, Any]:
        manifest = _read_manifest(path)
        if manifest["suite"] != self.suite:
            raise ResultsDirError(
                f"{self.out_dir} holds results of suite {manifest['suite']!r}, not {self.suite!r}; choose another --out"
            )
        return manifest

    def _start_over(self) -> None:
        """``fresh``: move the earlier results of this suite into ``previous/<UTC time>/``; delete nothing."""
        manifest = self.out_dir / MANIFEST_FILE
        if not os.path.lexists(manifest):  # nothing of ours to move (JSON lines alone are refused next)
            return
        self._own_manifest(manifest)
        results = self.out_dir / RESULTS_FILE
        count = (
            len(scan_jsonl(read_regular_file(results), key="key", validate=self.problem)[0]) if results.exists() else 0
        )
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
        parent = self.out_dir / PREVIOUS_DIR
        parent.mkdir(exist_ok=True)
        for n in range(1, 1000):
            target = parent / (stamp if n == 1 else f"{stamp}-{n}")
            try:
                target.mkdir()
                break
            except FileExistsError:
                continue
        else:  # pragma: no cover - a thousand --fresh runs within one second
            raise ResultsDirError(f"--out {self.out_dir}: no free name for the earlier results in {parent}")
        moved = [name for name in _FRESH_ITEMS if os.path.lexists(self.out_dir / name)]
        for name in moved:
            os.replace(self.out_dir / name, target / name)
        fsync_dir(target)
        fsync_dir(self.out_dir)
        self.previous = target
        trials = f"{count} trial" + ("" if count == 1 else "s")
        self.notes.append(
            f"started over (fresh): moved the earlier results ({trials}; {', '.join(moved)}) to {target}; "
            "nothing was deleted"
        )

    def _check_manifest(self) -> None:
        path = self.out_dir / MANIFEST_FILE
        if os.path.lexists(path):
            manifest = self._own_manifest(path)
        elif any(self.out_dir.glob("*.jsonl")):
            raise ResultsDirError(f"{self.out_dir} has JSON lines but no {MANIFEST_FILE}; not a steer-bench directory")
        else:
            manifest = {"schema": SCHEMA_VERSION, "suite": self.suite, "created": utc_now(), "sessions": []}
            atomic_write_text(path, json.dumps(manifest, indent=2, sort_keys=True) + "\n")
        self._manifest = manifest

    def _repair_and_load(self) -> None:
        data = read_regular_file(self.results_path) if self.results_path.exists() else b""
        self.records, kept, report = scan_jsonl(data, key="key", validate=self.problem)
        self._keys = {r["key"] for r in self.records}
        if report.clean:
            return
        quarantined: list[tuple[int | None, str, bytes]] = [(b.line, b.reason, b.raw) for b in report.bad_lines]
        if report.torn_tail:
            quarantined.append((None, "torn last line", report.torn_tail))
        if quarantined:
            at = utc_now()
            _append(self.out_dir / DISCARDED_FILE, b"".join(_quarantine_entry(at, *q) for q in quarantined))
            if report.torn_tail:
                self.notes.append(f"dropped a torn last line ({len(report.torn_tail)} bytes) from {RESULTS_FILE}")
            if report.bad_lines:
                bad = report.bad_lines
                self.notes.append(
                    f"quarantined {count_lines(bad)} of {RESULTS_FILE} in {DISCARDED_FILE}: {name_lines(bad)}"
                )
            atomic_write_bytes(self.results_path, b"".join(raw + b"\n" for raw in kept))
        else:  # only the newline of a finished last record is missing
            _append(self.results_path, b"\n")
        if report.missing_newline:
            self.notes.append(f"the last record of {RESULTS_FILE} had no newline: kept, newline appended")

    # ---------------------------------------------------------------- writing
    def append(self, record: Mapping[str, Any]) -> None:
        """Append one finished trial (flushed and fsync-ed before returning).

        ``ValueError`` for a record that :func:`record_problem` refuses (it
        would be quarantined on the next open) or whose key is recorded already.
        """
        if self._fd is None:
            raise RuntimeError("ResultStore is not open")
        data = encode_record(record)
        problem = self.problem(json.loads(data))
        if problem is not None:
            raise ValueError(f"not a valid record of {self.results_path}: {problem}")
        if record["key"] in self._keys:
            raise ValueError(f"trial {record['key']} is already recorded in {self.results_path}")
        _write_all(self._fd, data)
        os.fsync(self._fd)
        self.records.append(dict(record))
        self._keys.add(record["key"])

    def append_failure(self, record: Mapping[str, Any]) -> None:
        """Log a failed trial to ``failures.jsonl`` (informational; the trial is re-run on resume)."""
        _append(self.out_dir / FAILURES_FILE, encode_record(record))

    def start_session(self, info: Mapping[str, Any]) -> None:
        """Record one ``run`` invocation in ``manifest.json`` (atomic rewrite)."""
        if self._fd is None:
            raise RuntimeError("ResultStore is not open")
        manifest = dict(self._manifest)
        manifest["sessions"] = [*manifest.get("sessions", []), {"started": utc_now(), **dict(info)}]
        atomic_write_text(self.out_dir / MANIFEST_FILE, json.dumps(manifest, indent=2, sort_keys=True) + "\n")
        self._manifest = manifest


def _quarantine_entry(at: str, line: int | None, reason: str, raw: bytes) -> bytes:
    entry: dict[str, Any] = {"at": at, "file": RESULTS_FILE, "line": line, "reason": reason}
    try:
        entry["bytes"] = raw.decode("utf-8")
    except UnicodeDecodeError:
        entry["bytes"] = raw.decode("utf-8", "replace")
        entry["base64"] = base64.b64encode(raw).decode("ascii")
    return encode_record(entry)


def _open_append(path: Path, *, write: bool = True) -> int:
    """An ``O_APPEND`` descriptor of ``path`` (created with the usual ``0o666 & ~umask`` mode)."""
    created = not os.path.lexists(path)
    flags = (os.O_WRONLY | os.O_APPEND if write else os.O_RDWR) | os.O_CREAT
    fd = os.open(path, flags, 0o666)
    if created:
        fsync_dir(path.parent)
    return fd


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def _append(path: Path, data: bytes) -> None:
    fd = _open_append(path)
    try:
        _write_all(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


def _lookup_acceptor(suite: str) -> Callable[[str], bool] | None:
    """Which record suites a directory of ``suite`` holds (``None``: any, the suite is not registered here)."""
    try:
        return get_suite(suite).accepts_records_of
    except KeyError:
        return None


def load_results(
    out_dir: str | os.PathLike[str],
) -> tuple[dict[str, Any], list[dict[str, Any]], ReadReport]:
    """Manifest and valid records of a results directory, read-only (no lock, no repair).

    Bad lines are skipped and listed in the report (:meth:`ReadReport.describe`);
    the next :meth:`ResultStore.open` quarantines them. ``FileNotFoundError``
    when ``out_dir`` is not a steer-bench directory, :class:`ResultsDirError`
    when its manifest or results file cannot be read.

    >>> load_results("/nonexistent/steer-bench-dir")
    Traceback (most recent call last):
    FileNotFoundError: no results directory at /nonexistent/steer-bench-dir
    """
    if not isinstance(out_dir, (str, os.PathLike)):
        raise TypeError(f"out_dir must be a str or os.PathLike path, got {describe(out_dir)}")
    out_dir = Path(out_dir)
    if not str(out_dir).strip() or not out_dir.is_dir():
        raise FileNotFoundError(f"no results directory at {out_dir}")
    manifest_path = out_dir / MANIFEST_FILE
    if not os.path.lexists(manifest_path):
        raise FileNotFoundError(f"{out_dir} has no {MANIFEST_FILE}; is it a steer-bench --out directory?")
    manifest = _read_manifest(manifest_path)
    accepts = _lookup_acceptor(manifest["suite"])
    records, report = read_jsonl(
        out_dir / RESULTS_FILE, validate=lambda rec: record_problem(rec, accepts_suite=accepts)
    )
    return manifest, records, report
