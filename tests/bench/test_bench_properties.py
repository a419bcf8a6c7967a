"""Property tests: random bad lines, records, requests, parameters and command lines at steer-bench's boundaries.

Each property asserts a clean, documented outcome: bad lines quarantined with
every good line kept byte for byte, ``TypeError`` / ``ValueError`` for a bad
request, exit 2 with one line for a bad command line, never a traceback.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from steer_envs.bench.cli import main
from steer_envs.bench.records import encode_record, record_problem
from steer_envs.bench.report import render, summarize
from steer_envs.bench.runner import build_request
from steer_envs.bench.store import DISCARDED_FILE, RESULTS_FILE, ResultStore, load_results
from steer_envs.bench.suite import Trial, get_suite
from steer_envs.bench.suites.selftest import SelftestParams

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12,
)


def _record(seed: int, value: float = 1.0) -> dict:
    trial = Trial("selftest", None, "mc", seed, {"samples": 10}, "math:sqrt")
    return {"key": trial.key, "config": trial.config, "seed": seed, "metrics": {"pi": value}}


@st.composite
def bad_lines(draw) -> bytes:
    kind = draw(st.sampled_from(["json", "bytes", "mutated"]))
    if kind == "json":
        return json.dumps(draw(json_values)).encode()
    if kind == "bytes":
        return draw(st.binary(min_size=1, max_size=40).filter(lambda b: b"\n" not in b and b.strip()))
    record = _record(draw(st.integers(0, 5)))
    field = draw(st.sampled_from(["key", "config", "seed", "metrics", "extra", "schema"]))
    junk = draw(json_values.filter(lambda v: not isinstance(v, dict) or field not in ("config", "extra")))
    if field == "metrics":
        junk = {"pi": junk}
    bad = {**record, field: junk}
    if record_problem(bad) is None:  # the junk happened to fit (a numeric or null metric, schema 1)
        bad["seed"] = "not a seed"
    return json.dumps(bad).encode()


@SETTINGS
@given(
    items=st.lists(
        st.one_of(st.integers(0, 30).map(lambda s: ("good", s)), bad_lines().map(lambda b: ("bad", b))), max_size=12
    ),
    tail=st.sampled_from(["none", "torn", "no-newline"]),
    cut=st.integers(1, 200),
)
def test_open_keeps_every_good_line_and_quarantines_every_bad_one(items, tail, cut):
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        with ResultStore(out, "selftest"):
            pass
        data, expected, seen, n_bad = b"", [], set(), 0
        for kind, item in items:
            if kind == "good":
                line = encode_record(_record(item))
                if item in seen:
                    n_bad += 1  # a duplicate
                else:
                    seen.add(item)
                    expected.append(line)
            else:
                line, n_bad = item + b"\n", n_bad + 1
            data += line
        last = encode_record(_record(99))
        if tail == "torn":
            data += last[: min(cut, len(last) - 2)]
        elif tail == "no-newline":
            data += last[:-1]
            expected.append(last)
        (out / RESULTS_FILE).write_bytes(data)

        _, records, _ = load_results(out)  # `report`: reads around the bad lines
        assert [encode_record(r) for r in records] == expected
        with ResultStore(out, "selftest") as store:  # `run`: quarantines them
            assert [encode_record(r) for r in store.records] == expected
        assert (out / RESULTS_FILE).read_bytes() == b"".join(expected)
        discarded = out / DISCARDED_FILE
        quarantined = discarded.read_text().splitlines() if discarded.exists() else []
        assert len(quarantined) == n_bad + (tail == "torn")
        assert load_results(out)[2].clean


@SETTINGS
@given(value=json_values)
def test_record_problem_never_raises(value):
    problem = record_problem(value)
    assert problem is None or isinstance(problem, str)
    if isinstance(value, dict):
        assert isinstance(record_problem({**_record(0), "config": value}), str)


@SETTINGS
@given(
    seeds=st.one_of(st.none(), st.integers(-5, 10**15), st.lists(st.integers(-3, 10**6), max_size=5), json_values),
    trials=st.one_of(st.none(), st.integers(-3, 10**12), st.floats(), st.text(max_size=3)),
    params=st.one_of(
        st.none(),
        json_values,
        st.dictionaries(st.sampled_from(["samples", "sleep", "fail_seeds", "x"]), json_values, max_size=3),
    ),
)
def test_bad_requests_raise_type_or_value_errors(seeds, trials, params):
    suite = get_suite("selftest")
    try:
        request = build_request(suite, seeds=seeds, trials=trials, params=params)
        suite.plan(request)
    except (TypeError, ValueError):
        pass


@SETTINGS
@given(values=st.dictionaries(st.sampled_from(["samples", "sleep", "fail_seeds"]), json_values, max_size=3))
def test_bad_parameters_name_the_parameter(values):
    try:
        params = SelftestParams.from_json(values)
    except ValueError as exc:
        assert "parameter '" in str(exc)
    else:
        assert 1 <= params.samples <= 10**8 and math.isfinite(params.sleep)


finite = st.floats(allow_nan=False, allow_infinity=False)


@SETTINGS
@given(values=st.lists(st.one_of(st.none(), finite, st.sampled_from([1.7e308, -1.7e308, 5e-324])), min_size=1,
                       max_size=6))  # fmt: skip
def test_reports_of_extreme_but_valid_metrics_render(values):
    records = [{**_record(i), "metrics": {"pi": v}} for i, v in enumerate(values)]
    tables = summarize(records)
    for fmt in ("md", "csv", "json"):
        assert render(tables, fmt)


option_values = st.one_of(
    st.sampled_from(["", " ", "0", "-1", "1", "2", "abc", "1e999", "NaN", "nope", "samples=3", "x=", "=", "[]"]),
    st.text(max_size=6),
)
options = st.sampled_from(
    ["--seeds", "--trials", "--param", "--workers", "--executor", "--env", "--method", "--out", "--plugin", "--format"]
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    command=st.sampled_from(["run", "report", "list"]), pairs=st.lists(st.tuples(options, option_values), max_size=3)
)
def test_random_command_lines_exit_cleanly(command, pairs):
    with tempfile.TemporaryDirectory() as tmp:
        argv = [command]
        if command != "list":
            argv.append("selftest" if command == "run" else tmp)
        for option, value in pairs:
            if option == "--workers" and value.strip().isdigit() and int(value) > 1:
                value = "1"  # a process pool per example would be slow; its errors are tested elsewhere
            if option == "--trials" and value.strip().isdigit():
                value = str(min(int(value), 100))
            argv += [option, value]
        if command == "run":
            argv += ["--out", str(Path(tmp) / "o"), "--no-progress", "--seeds", "1"]
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                status = main(argv)
            except SystemExit as exc:
                status = exc.code
        text = err.getvalue()
        assert "Traceback" not in text
        assert status in (0, 1, 2), (argv, status, text)
        if status == 2:
            assert len(text.strip().splitlines()) == 1, (argv, text)
