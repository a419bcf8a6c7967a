"""Fuzz pass over steer-bench's boundaries: the command line, results directories, the Python API, kill + resume.

Each case must end within a per-case timeout in a documented outcome:

* the command line: exit 0/1, or exit 2 with exactly one line on stderr; never a traceback;
* a results directory with random bad lines: ``report`` and ``run`` still work, every good
  line is kept byte for byte, every bad one is quarantined, no trial is run twice;
* the Python API (requests, stores, readers, reports, trials, every suite's parameters):
  a result or ``TypeError`` / ``ValueError`` (``KeyError`` for an unknown suite);
* ``kill -9`` of a run (sequential or ``--workers 2``) at a random moment: no worker
  outlives it, and the resume gives exactly the planned trials, none twice.

Run with ``pytest -m slow tests/fuzz/test_fuzz_bench.py -s``; it prints the counts.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_helpers import bench_env, descendants, kill_all, run_cli, wait_gone

from steer_envs.bench.cli import main
from steer_envs.bench.executors import ExecutorStartError
from steer_envs.bench.records import encode_record, read_jsonl, record_problem
from steer_envs.bench.report import render, summarize
from steer_envs.bench.runner import build_request, plan_trials, run_suite
from steer_envs.bench.store import (
    DISCARDED_FILE,
    MANIFEST_FILE,
    RESULTS_FILE,
    ResultStore,
    StoreLockedError,
    load_results,
)
from steer_envs.bench.suite import Trial, get_suite, suites

pytestmark = pytest.mark.slow

PER_CASE_S = 30.0
DOCUMENTED = (TypeError, ValueError, KeyError, ImportError, StoreLockedError, ExecutorStartError, FileNotFoundError)
COUNTS: Counter[str] = Counter()


class _Hang(BaseException):
    """Raised by SIGALRM: the case ran past its timeout."""


def _alarm(*_: object) -> None:
    raise _Hang


def _case(boundary: str, fn: Callable[[], str], *, errors_ok: bool = True) -> None:
    """Run one case under the timeout; ``fn`` returns its outcome label (or raises).

    With ``errors_ok=False`` (cases that must succeed) a documented error counts as ``LOST``.
    """
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, PER_CASE_S)
    try:
        outcome = fn()
    except _Hang:
        outcome = "HANG"
    except DOCUMENTED as exc:
        outcome = f"error {type(exc).__name__}" if errors_ok else f"LOST: {type(exc).__name__}: {exc}"[:300]
    except Exception as exc:
        outcome = "TRACEBACK " + "".join(traceback.format_exception_only(exc)).strip()[:300]
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    COUNTS[f"{boundary}: {outcome}"] += 1
    COUNTS["cases"] += 1
    COUNTS[f"cases {boundary}"] += 1


# ------------------------------------------------------------------------------------ random values
JUNK: list[Any] = [None, True, False, 0, -1, 1, 2**70, -(2**70), 1.5, -0.0, math.nan, math.inf, -math.inf, 1e308,
                   "", " ", "1", "abc", "nope", "\x00", "é", b"bytes", [], [1], ["a"], [[[]]], {}, {"a": 1},
                   {"key": "x"}, (1, 2), object(), 1 + 2j]  # fmt: skip


def _junk(rng: random.Random, depth: int = 0) -> Any:
    roll = rng.random()
    if depth < 2 and roll < 0.15:
        return [_junk(rng, depth + 1) for _ in range(rng.randint(0, 3))]
    if depth < 2 and roll < 0.3:
        return {rng.choice(["a", "key", "suite", "seed", "metrics", "1"]): _junk(rng, depth + 1) for _ in range(2)}
    return rng.choice(JUNK)


def _json_junk(rng: random.Random) -> Any:
    value = _junk(rng)
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        return rng.choice([None, 1, "x", [1, "a"], {"a": None}])
    return value


def _record(seed: int, suite: str = "selftest") -> dict[str, Any]:
    trial = Trial(suite, None, "mc", seed, {"samples": 10}, "math:sqrt")
    return {"key": trial.key, "config": trial.config, "seed": seed, "metrics": {"pi": 3.0 + seed / 100}}


def _bad_line(rng: random.Random) -> bytes:
    kind = rng.randrange(6)
    if kind == 0:
        return json.dumps(_json_junk(rng)).encode()
    if kind == 1:
        return bytes(rng.randrange(256) for _ in range(rng.randint(1, 30))).replace(b"\n", b"?").strip() or b"?"
    if kind == 2:
        return b"[" * rng.randint(1000, 200_000)  # deep nesting
    if kind == 3:
        rec = _record(rng.randrange(50))
        rec["config"] = {**rec["config"], "suite": rng.choice(["smoke", "other", ""])}
        return json.dumps(rec).encode()
    if kind == 4:
        return encode_record(_record(rng.randrange(50)))[: rng.randint(1, 60)].replace(b"\n", b"")
    rec = _record(rng.randrange(50))
    field = rng.choice(["key", "config", "seed", "metrics", "extra", "schema"])
    rec[field] = _json_junk(rng)
    if field == "metrics" and isinstance(rec[field], dict) and not rec[field]:
        rec[field] = {"pi": "x"}
    if field == "extra" and isinstance(rec[field], dict):
        rec[field] = [rec[field]]
    if record_problem(rec) is None:  # the junk happened to fit (schema 1, numeric metrics): break it for sure
        rec["seed"] = "not a seed"
    return json.dumps(rec).encode()


# ------------------------------------------------------------------------------------ the command line
def _cli_outcome(argv: list[str]) -> str:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code if isinstance(exc.code, int) else 2
    text = err.getvalue()
    if "Traceback" in text:
        raise AssertionError(f"traceback for {argv}: {text[-500:]}")
    if status == 2 and len(text.strip().splitlines()) != 1:
        raise AssertionError(f"exit 2 with {len(text.strip().splitlines())} lines for {argv}: {text!r}")
    if status not in (0, 1, 2):
        raise AssertionError(f"exit {status} for {argv}")
    return f"cli exit {status}"


def _layout(tmp: Path, rng: random.Random) -> Path:
    """A path for --out / DIR / --plots-dir: fine, a file, under a file, a directory with a broken layout."""
    kind = rng.randrange(7)
    afile = tmp / "afile"
    afile.write_text("x")
    if kind == 0:
        return afile
    if kind == 1:
        return afile / "under"
    if kind == 2:
        d = tmp / "badres"
        (d / RESULTS_FILE).mkdir(parents=True, exist_ok=True)
        (d / MANIFEST_FILE).write_text(json.dumps({"suite": "selftest"}))
        return d
    if kind == 3:
        d = tmp / "badman"
        d.mkdir(exist_ok=True)
        (d / MANIFEST_FILE).write_text(rng.choice(["[]", "garbage", "{}", '{"suite": 1}', "[" * 50_000, "\xff"]))
        return d
    if kind == 4:
        d = tmp / "fifo"
        d.mkdir(exist_ok=True)
        (d / MANIFEST_FILE).write_text(json.dumps({"suite": "selftest"}))
        if not (d / RESULTS_FILE).exists():
            os.mkfifo(d / RESULTS_FILE)
        return d
    return tmp / f"fresh{rng.randrange(1000)}"


def _cli_case(rng: random.Random) -> str:
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        command = rng.choice(["run", "run", "report", "list"])
        argv = [command]
        if command == "run":
            argv.append(rng.choice(["selftest", "selftest", "ltl-translation", "nope", "", "toy"]))
            argv += ["--no-progress", "--seeds", "1", "--trials", "20", "--out", str(tmp / "default")]
        elif command == "report":
            argv.append(str(_layout(tmp, rng)) if rng.random() < 0.8 else rng.choice(["", "/nonexistent", " "]))
        elif rng.random() < 0.5:
            argv.append(rng.choice(["selftest", "nope", "smoke", ""]))
        options = {
            "run": ["--seeds", "--trials", "--param", "--workers", "--executor", "--address", "--env", "--method",
                    "--out", "--plugin", "--bogus"],
            "report": ["--format", "--plots", "--plots-dir", "--plugin"],
            "list": ["--plugin"],
        }[command]  # fmt: skip
        values = ["", " ", "0", "-1", "1", "2", "3", "abc", "1e999", "NaN", "1000000000000", "samples=abc",
                  "sleep=NaN", "sleep=-1", "samples=0", "fail_seeds=[1]", "samples=5", "x=1", "=", "[]", "md",
                  "json", "xml", "local", "ray", "auto", "127.0.0.1:1", "mc", "zz", "no_such_plugin_xyz",
                  "steer_envs.bench.suites.selftest", "ConvexMode-v0", "\x01"]  # fmt: skip
        for _ in range(rng.randint(0, 4)):
            option = rng.choice(options)
            if option in ("--plots", "--bogus"):
                argv.append(option)
                continue
            if option in ("--out", "--plots-dir"):
                argv += [option, str(_layout(tmp, rng))]
                continue
            value = rng.choice(values)
            if option == "--workers" and value not in ("0", "-1", "abc", "", " ", "1000000000000"):
                value = "1"  # process pools are fuzzed by the kill cases below
            if option == "--executor" and value == "ray" and rng.random() < 0.7:
                argv += ["--address", "127.0.0.1:1"]  # a real Ray start would take the whole case budget
            argv += [option, value]
        if command == "run" and "ray" in argv and "--address" not in argv:
            argv += ["--address", "127.0.0.1:1"]
        return _cli_outcome(argv)


# ------------------------------------------------------------------------------------ results directories
def _directory_case(rng: random.Random) -> str:
    """Random good and bad lines (and a tail) in results.jsonl: report then run keep the good, quarantine the bad."""
    with tempfile.TemporaryDirectory() as tmp_name:
        out = Path(tmp_name) / "out"
        seeds = rng.randint(1, 4)
        argv = ["run", "selftest", "--method", "mc", "--seeds", str(seeds), "--trials", "20", "--out", str(out),
                "--no-progress"]  # fmt: skip
        assert _cli_outcome(argv) == "cli exit 0"
        good_lines = (out / RESULTS_FILE).read_bytes().split(b"\n")[:-1]
        data, n_bad = b"", 0
        lines = list(good_lines)
        for _ in range(rng.randint(1, 6)):
            lines.insert(rng.randint(0, len(lines)), b"\x00BAD" + bytes([rng.randrange(256)]))
        kept = []
        for line in lines:
            if line.startswith(b"\x00BAD"):
                bad = _bad_line(rng)
                data += bad + b"\n"
                n_bad += 1
            elif line in kept:
                data += line + b"\n"
                n_bad += 1
            else:
                data += line + b"\n"
                kept.append(line)
        tail = rng.choice(["none", "torn", "no-newline", "dup"])
        if tail == "torn":
            data += encode_record(_record(77))[: rng.randint(1, 40)]
        elif tail == "no-newline":
            data = data[:-1]
        elif tail == "dup":
            data += good_lines[0] + b"\n"
            n_bad += 1
        (out / RESULTS_FILE).write_bytes(data)
        _, records, _ = load_results(out)
        if [encode_record(r).rstrip(b"\n") for r in records] != kept:
            return "LOST records in report"
        assert _cli_outcome(["report", str(out), "--format", rng.choice(["md", "csv", "json"])]) == "cli exit 0"
        assert _cli_outcome([*argv[:5], str(seeds + 1), *argv[6:]]) == "cli exit 0"
        final = (out / RESULTS_FILE).read_bytes()
        if not final.startswith(b"".join(line + b"\n" for line in kept)):
            return "LOST good lines"
        final_records, report = read_jsonl(out / RESULTS_FILE)
        keys = [r["key"] for r in final_records]
        if not report.clean or len(keys) != seeds + 1 or len(set(keys)) != len(keys):
            return "LOST or repeated trials"
        discarded = out / DISCARDED_FILE
        quarantined = len(discarded.read_text().splitlines()) if discarded.exists() else 0
        if quarantined != n_bad + (tail == "torn"):
            return f"LOST quarantine count {quarantined} != {n_bad + (tail == 'torn')}"
        return "directory repaired"


# ------------------------------------------------------------------------------------ the Python API
def _param_classes() -> list[Any]:
    return [s for s in suites() if s.defaults.to_json()]


def _api_case(rng: random.Random) -> str:
    boundary = rng.randrange(8)
    if boundary == 0:  # every suite's parameters
        suite = rng.choice(_param_classes())
        names = [*list(suite.param_names), "nope"]
        values = {rng.choice(names): _junk(rng) for _ in range(rng.randint(1, 3))}
        suite.resolve_params(values)
        return "accepted"
    if boundary == 1:
        suite = get_suite(rng.choice(["selftest", "ltl-translation", "smoke"]))
        seeds = rng.choice([_junk(rng), rng.randint(-2, 10**13), [rng.randint(-2, 5) for _ in range(3)]])
        request = build_request(
            suite,
            seeds=seeds,
            trials=rng.choice([None, _junk(rng)]),
            params=rng.choice([None, _junk(rng)]),
            envs=rng.choice([None, _junk(rng)]),
            methods=rng.choice([None, _junk(rng)]),
        )
        plan_trials(suite, request)
        return "accepted"
    if boundary == 2:
        with tempfile.TemporaryDirectory() as tmp:
            out = rng.choice([_junk(rng), tmp, str(Path(tmp) / "x")])
            run_suite(
                rng.choice(["selftest", _junk(rng)]),
                out,
                seeds=rng.choice([1, _junk(rng)]),
                methods=["mc"],
                params={"samples": 10},
                progress=rng.choice([False, _junk(rng)]),
                executor=rng.choice(["local", _junk(rng)]),
                workers=rng.choice([None, 1, _junk(rng)]),
            )
        return "accepted"
    if boundary == 3:
        with tempfile.TemporaryDirectory() as tmp:
            store = ResultStore(rng.choice([tmp, _junk(rng)]), rng.choice(["s", _junk(rng)]))
            with store:
                store.append(rng.choice([_junk(rng), _record(1, "s"), {**_record(2, "s"), "seed": _junk(rng)}]))
        return "accepted"
    if boundary == 4:
        value = _json_junk(rng)
        problem = record_problem(value)
        assert problem is None or isinstance(problem, str)
        return "record judged"
    if boundary == 5:
        records = [rng.choice([_record(i), {**_record(i), "metrics": {"pi": _junk(rng)}}, _junk(rng)])
                   for i in range(rng.randint(0, 4))]  # fmt: skip
        render(summarize(rng.choice([records, _junk(rng)])), rng.choice(["md", "csv", "json"]))
        return "accepted"
    if boundary == 6:
        Trial(*(rng.choice([good, _junk(rng)]) for good in ("selftest", None, "mc", 0, {}, "math:sqrt")))
        return "accepted"
    get_suite(_junk(rng))
    return "accepted"


# ------------------------------------------------------------------------------------ kill + resume
def _kill_case(rng: random.Random, workers: int) -> str:
    with tempfile.TemporaryDirectory() as tmp_name:
        out = Path(tmp_name) / "run"
        seeds = 8
        argv = [
            "run",
            "selftest",
            "--seeds",
            str(seeds),
            "--trials",
            "100",
            "--param",
            "sleep=0.04",
            "--out",
            str(out),
            "--no-progress",
        ] + (["--workers", str(workers)] if workers > 1 else [])
        proc = subprocess.Popen(
            [sys.executable, "-m", "steer_envs.bench", *argv],
            env=bench_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        results = out / RESULTS_FILE
        time.sleep(rng.uniform(0.3, 3.0))  # any moment: start-up, mid-trial, mid-write, after the end
        children = descendants(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        survivors = wait_gone(children, 5.0)
        kill_all(survivors)
        if survivors:
            return f"LOST: {len(survivors)} orphan processes"
        if results.exists() and rng.random() < 0.5:
            with results.open("ab") as fh:
                fh.write(encode_record(_record(5))[: rng.randint(1, 50)])
        done = run_cli(*argv, timeout=120)
        if done.returncode != 0:
            return f"LOST: resume exit {done.returncode}: {done.stderr[-300:]}"
        records, report = read_jsonl(results)
        suite = get_suite("selftest")
        planned = {t.key for t in plan_trials(suite, build_request(suite, seeds=seeds, trials=100,
                                                                   params={"sleep": 0.04})).trials}  # fmt: skip
        keys = [r["key"] for r in records]
        if not report.clean or len(keys) != len(set(keys)) or set(keys) != planned:
            return "LOST or repeated trials after resume"
        return f"killed and resumed (workers={workers})"


# ------------------------------------------------------------------------------------ the pass
def test_fuzz_bench(tmp_path, monkeypatch):
    from steer_envs.bench.suite import load_plugins

    monkeypatch.chdir(tmp_path)  # junk `out` values such as "1" are relative folders: keep them out of the checkout

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    load_plugins(["steer_bench_testplugin"])
    rng = random.Random(15)
    for _ in range(260):
        _case("cli", lambda: _cli_case(rng))
    for _ in range(60):
        _case("directory", lambda: _directory_case(rng), errors_ok=False)
    for _ in range(400):
        _case("api", lambda: _api_case(rng))
    for i in range(12):
        _case("kill", lambda i=i: _kill_case(rng, 1 if i % 2 else 2), errors_ok=False)
    print("\nsteer-bench fuzz pass:")
    for name, count in sorted(COUNTS.items()):
        print(f"  {count:5d}  {name}")
    bad = {k: v for k, v in COUNTS.items() if k.split(": ", 1)[-1].startswith(("HANG", "TRACEBACK", "LOST"))}
    assert COUNTS["cases"] >= 500
    assert not bad, bad
