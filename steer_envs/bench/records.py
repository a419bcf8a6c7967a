"""Trial records and the JSON-lines files that hold them: strict encoding, validation, tolerant reading.

A record is one finished trial (:func:`record_problem` says what one must hold);
:func:`encode_record` writes it as one line of strict JSON and :func:`read_jsonl`
reads a file of them back, skipping (and reporting) a torn last line, lines that
are no record and duplicates. :class:`~steer_envs.bench.store.ResultStore`
appends them to a results directory's :data:`RESULTS_FILE`.
"""

from __future__ import annotations

import json
import math
import os
import stat
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from steer_envs.bench.suite import trial_key
from steer_envs.core.validation import describe

__all__ = [
    "RESULTS_FILE",
    "SCHEMA_VERSION",
    "BadLine",
    "ReadReport",
    "ResultsDirError",
    "encode_record",
    "read_jsonl",
    "record_problem",
    "utc_now",
]

#: the file of a results directory that holds its records, one a line
RESULTS_FILE = "results.jsonl"
SCHEMA_VERSION = 1
#: bad lines named one by one in a note (the rest are counted)
_NOTE_LINES = 5


class ResultsDirError(ValueError):
    """A results directory that cannot be used; the message names the path and what is wrong.

    Raised for a path that is (or lies under) a regular file, a folder that
    cannot be created or written, a ``manifest.json`` that is not a
    steer-bench manifest (garbage, ``[]``, no ``suite``), a directory of
    another suite, and a ``results.jsonl`` (or any other file of the layout)
    that is a folder, a FIFO or a broken link.
    """


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
    except RecursionError:
        raise ValueError("record is nested too deeply to be written as JSON") from None
    return (text + "\n").encode("utf-8")


def _finite_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def record_problem(
    record: Any, *, accepts_suite: Callable[[str], bool] | None = None, require_key: bool = True
) -> str | None:
    """What makes ``record`` not a valid trial record, or ``None`` when it is one.

    A record is a JSON object with ``config`` (``suite``: a non-empty string,
    ``env`` and ``method``: a string or null, ``params``: an object), an int
    ``seed``, ``metrics`` (names -> finite numbers or null), optionally an
    ``extra`` object and ``schema`` 1, and (with ``require_key``) the ``key``
    :func:`trial_key` gives for its config and seed. ``accepts_suite`` says
    which ``config.suite`` values belong (default: any). Never raises.

    >>> from steer_envs.bench.suite import Trial
    >>> t = Trial("selftest", None, "mc", 3, {}, "math:sqrt")
    >>> record_problem({"key": t.key, "config": t.config, "seed": 3, "metrics": {"pi": 3.1}}) is None
    True
    >>> record_problem({"key": t.key, "config": t.config, "seed": "3", "metrics": {}})
    "'seed' must be an int, got str '3'"
    >>> record_problem({"key": "x"})
    "'config' is missing"
    """
    if not isinstance(record, Mapping):
        return f"not a JSON object, got {type(record).__name__}"
    if "schema" in record and (not isinstance(record["schema"], int) or record["schema"] != SCHEMA_VERSION):
        return f"'schema' must be {SCHEMA_VERSION}, got {describe(record['schema'])}"
    if "config" not in record:
        return "'config' is missing"
    config = record["config"]
    problem = _config_problem(config, accepts_suite)
    if problem is not None:
        return problem
    seed = record.get("seed")
    if not isinstance(seed, int) or isinstance(seed, bool):
        return "'seed' is missing" if "seed" not in record else f"'seed' must be an int, got {describe(seed)}"
    metrics = record.get("metrics")
    if not isinstance(metrics, Mapping):
        return (
            "'metrics' is missing"
            if "metrics" not in record
            else f"'metrics' must be an object, got {describe(metrics)}"
        )
    for name, value in metrics.items():
        if value is not None and not _finite_number(value):
            return f"metric {name!r} must be a finite number or null, got {describe(value)}"
    if "extra" in record and not isinstance(record["extra"], Mapping):
        return f"'extra' must be an object, got {describe(record['extra'])}"
    return _key_problem(record, config, seed) if require_key else None


def _config_problem(config: Any, accepts_suite: Callable[[str], bool] | None) -> str | None:
    """What makes a record's ``config`` invalid (or of a suite ``accepts_suite`` refuses), or ``None``."""
    if not isinstance(config, Mapping):
        return f"'config' must be an object, got {describe(config)}"
    for name in ("suite", "env", "method", "params"):
        if name not in config:
            return f"'config.{name}' is missing"
    suite = config["suite"]
    if not isinstance(suite, str) or not suite:
        return f"'config.suite' must be a non-empty string, got {describe(suite)}"
    for name in ("env", "method"):
        if config[name] is not None and not isinstance(config[name], str):
            return f"'config.{name}' must be a string or null, got {describe(config[name])}"
    if not isinstance(config["params"], Mapping):
        return f"'config.params' must be an object, got {describe(config['params'])}"
    if accepts_suite is not None and not accepts_suite(suite):
        return f"a record of suite {suite!r}, which does not belong in this directory"
    return None


def _key_problem(record: Mapping[str, Any], config: Mapping[str, Any], seed: int) -> str | None:
    """What is wrong with a record's ``key`` (missing, or not :func:`trial_key` of its config and seed), or ``None``."""
    key = record.get("key")
    if not isinstance(key, str):
        return "'key' is missing" if "key" not in record else f"'key' must be a string, got {describe(key)}"
    try:
        expected = trial_key(config, seed)
    except (TypeError, ValueError, RecursionError):  # pragma: no cover - parsed JSON always serialises
        return "'config' cannot be hashed"
    if key != expected:
        return f"'key' {key!r} does not match its config and seed (expected {expected!r})"
    return None


BadKind = Literal["corrupt", "invalid", "duplicate"]


@dataclass(frozen=True)
class BadLine:
    """A complete line that a reader skipped: ``corrupt`` (not JSON), ``invalid`` (no record) or ``duplicate``."""

    line: int  # 1-based
    kind: BadKind
    reason: str
    raw: bytes = field(repr=False)


@dataclass
class ReadReport:
    """What :func:`read_jsonl` had to skip or fix."""

    torn_tail: bytes = b""  # bytes after the last newline that are not a record (a writer killed mid-line)
    bad_lines: list[BadLine] = field(default_factory=list)  # complete lines that were skipped
    missing_newline: bool = False  # the last line was a valid record without its newline (it is kept)

    @property
    def corrupt_lines(self) -> list[int]:
        """1-based numbers of the lines that are not a valid record (unparsable or invalid)."""
        return [b.line for b in self.bad_lines if b.kind != "duplicate"]

    @property
    def duplicates(self) -> int:
        """Records whose key was already seen (the first one is kept)."""
        return sum(b.kind == "duplicate" for b in self.bad_lines)

    @property
    def clean(self) -> bool:
        return not self.torn_tail and not self.bad_lines and not self.missing_newline

    def describe(self, filename: str = RESULTS_FILE) -> list[str]:
        """One line per kind of problem (the bad lines named up to five, then counted).

        >>> ReadReport(torn_tail=b'{"ke', missing_newline=False).describe()
        ['a torn last line of results.jsonl (4 bytes; a writer was killed mid-line)']
        """
        notes = []
        if self.torn_tail:
            notes.append(f"a torn last line of {filename} ({len(self.torn_tail)} bytes; a writer was killed mid-line)")
        if self.bad_lines:
            notes.append(f"{count_lines(self.bad_lines)} of {filename} skipped: {name_lines(self.bad_lines)}")
        if self.missing_newline:
            notes.append(f"the last record of {filename} had no newline (kept: the trial had finished)")
        return notes


def count_lines(bad: list[BadLine]) -> str:
    """``"1 line"`` / ``"N lines"``."""
    return f"{len(bad)} line" + ("" if len(bad) == 1 else "s")


def name_lines(bad: list[BadLine]) -> str:
    """The first bad lines with their reasons, the rest counted."""
    named = "; ".join(f"line {b.line}: {b.reason}" for b in bad[:_NOTE_LINES])
    return named + (f"; and {len(bad) - _NOTE_LINES} more" if len(bad) > _NOTE_LINES else "")


class _NotStrict(ValueError):
    pass


def _no_constant(name: str) -> Any:
    raise _NotStrict(name)


def parse_json_line(raw: bytes) -> tuple[Any, str | None]:
    """``(value, None)`` for a line of strict JSON, ``(None, reason)`` otherwise."""
    try:
        return json.loads(raw, parse_constant=_no_constant), None
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except json.JSONDecodeError as exc:
        return None, f"not JSON ({exc.msg} at column {exc.colno})"
    except _NotStrict as exc:
        return None, f"not strict JSON ({exc} is no JSON number)"
    except RecursionError:
        return None, "JSON nested too deeply"


def scan_jsonl(
    data: bytes, *, key: str | None, validate: Callable[[dict[str, Any]], str | None] | None
) -> tuple[list[dict[str, Any]], list[bytes], ReadReport]:
    """Records, the raw bytes of their lines (no newline) and the report for the content of a JSON-lines file."""
    report = ReadReport()
    records: list[dict[str, Any]] = []
    kept: list[bytes] = []
    seen: dict[str, int] = {}
    lines = data.split(b"\n")
    tail = lines.pop()  # after the last newline: b"" for a complete file
    if tail and not tail.strip():
        tail = b""
    for lineno, raw in enumerate([*lines, tail], start=1):
        last = lineno == len(lines) + 1
        if not raw.strip():
            continue
        value, reason = parse_json_line(raw)
        kind: BadKind = "corrupt"
        if reason is None:
            kind = "invalid"
            if not isinstance(value, dict):
                reason = f"not a JSON object, got {type(value).__name__}"
            elif key is not None and not isinstance(value.get(key), str):
                reason = f"no string {key!r}"
            elif validate is not None:
                reason = validate(value)
        if reason is None and key is not None and value[key] in seen:
            kind, reason = "duplicate", f"duplicate of line {seen[value[key]]} (key {value[key]})"
        if reason is not None:
            if last and kind == "corrupt":
                report.torn_tail = raw
            else:
                report.bad_lines.append(
                    BadLine(lineno, kind, reason + (" (last line, no newline)" if last else ""), raw)
                )
            continue
        if key is not None:
            seen[value[key]] = lineno
        if last:
            report.missing_newline = True
        records.append(value)
        kept.append(raw)
    return records, kept, report


def read_jsonl(
    path: str | os.PathLike[str],
    *,
    key: str | None = "key",
    validate: Callable[[dict[str, Any]], str | None] | None = None,
) -> tuple[list[dict[str, Any]], ReadReport]:
    r"""Records of a JSON-lines file, tolerating a torn last line and bad lines.

    A line is kept when it parses as a JSON object, carries a string ``key``
    (when given) and passes ``validate`` (a function returning what is wrong,
    or ``None``); with ``key``, later duplicates of a key are dropped. Skipped
    lines are listed in the report. A last line without its newline is kept
    when it is a valid record, else reported as the torn tail. A missing file
    reads as empty; anything but a regular file raises :class:`ResultsDirError`.

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp) / "r.jsonl"
    ...     _ = path.write_bytes(b'{"key": "a"}\n{"key": "a"}\nnot json\n{"key": "b", "tor')
    ...     records, report = read_jsonl(path)
    >>> [r["key"] for r in records], report.duplicates, report.corrupt_lines, report.torn_tail
    (['a'], 1, [3], b'{"key": "b", "tor')
    """
    path = Path(path)
    if not os.path.lexists(path):
        return [], ReadReport()
    records, _, report = scan_jsonl(read_regular_file(path), key=key, validate=validate)
    return records, report


def read_regular_file(path: Path) -> bytes:
    """The bytes of ``path`` (a regular file); :class:`ResultsDirError` otherwise or when it cannot be read."""
    require_regular_file(path)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise ResultsDirError(f"cannot read {path}: {exc.strerror or exc}") from None


def require_regular_file(path: Path) -> None:
    """``ResultsDirError`` unless ``path`` is missing or a regular file (a link to one is fine)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if os.path.islink(path):
            raise ResultsDirError(f"{path} is a broken symbolic link") from None
        return
    except OSError as exc:
        raise ResultsDirError(f"cannot use {path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "not a regular file"
        raise ResultsDirError(f"{path} is {kind}; a steer-bench directory holds a regular file there")
