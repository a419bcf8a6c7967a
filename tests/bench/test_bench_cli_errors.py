"""Every usage or configuration error of ``steer-bench`` is one line on stderr and exit 2, never a traceback.

And one bad record in ``results.jsonl`` blocks neither ``report`` nor ``run``.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from bench_helpers import run_cli

from steer_envs.bench.cli import main
from steer_envs.bench.store import DISCARDED_FILE, MANIFEST_FILE, RESULTS_FILE, ResultStore


def _exit_and_stderr(argv: list[str], capsys) -> tuple[int, str]:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code if isinstance(exc.code, int) else 2
    return status, capsys.readouterr().err


def assert_usage_error(argv: list[str], capsys, match: str) -> str:
    status, err = _exit_and_stderr(argv, capsys)
    assert status == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"expected one line, got: {err!r}"
    assert match in lines[0], lines[0]
    assert lines[0].startswith("steer-bench")
    return lines[0]


def _run(out: str | Path, *extra: str) -> list[str]:
    return ["run", "selftest", "--seeds", "1", "--trials", "50", "--out", str(out), "--no-progress", *extra]


@pytest.fixture
def finished(tmp_path, capsys) -> Path:
    """A results directory with 2 finished selftest trials."""
    out = tmp_path / "done"
    assert main(_run(out)) == 0
    capsys.readouterr()
    return out


@pytest.fixture
def afile(tmp_path) -> Path:
    path = tmp_path / "afile"
    path.write_text("not a folder")
    return path


# ------------------------------------------------------------------------------------- run
@pytest.mark.parametrize(
    ("argv_tail", "match"),
    [
        (["--seeds", "1000000000000"], "at most 100000 trials per run"),
        (["--seeds", "99999999999999999999999999"], "at most 100000 trials per run"),
        (["--seeds", "0"], "positive integer"),
        (["--seeds", "-3"], "positive integer"),
        (["--seeds", "abc"], "positive integer"),
        (["--trials", "0"], "positive integer"),
        (["--trials", "1000000000000"], "'samples' must be <= 100000000"),
        (["--workers", "0"], "positive integer"),
        (["--workers", "1000000"], "workers must be an int in [1,"),
        (["--executor", "dask"], "invalid choice: 'dask'"),
        (["--address", "auto"], "only used by the ray executor"),
        (["--param", "samples"], "expected KEY=VALUE"),
        (["--param", "=3"], "expected KEY=VALUE"),
        (["--param", "speed=3"], "has no parameter 'speed'"),
        (["--param", "sleep=abc"], "'sleep' must be finite float"),
        (["--param", "sleep=NaN"], "'sleep' must be finite float"),
        (["--param", "sleep=1e999"], "'sleep' must be finite float"),
        (["--param", "sleep=-1"], "'sleep' must be in [0, 3600]"),
        (["--param", 'fail_seeds=["a"]'], "'fail_seeds' must be a list of int"),
        (["--env", "Nope-v0"], "unknown env 'Nope-v0'"),
        (["--method", "zz"], "unknown method 'zz'"),
        (["--plugin", "no_such_module_xyz"], "cannot import steer-bench plugin module 'no_such_module_xyz'"),
        (["--bogus"], "unrecognized arguments: --bogus"),
    ],
)
def test_run_option_errors(tmp_path, capsys, argv_tail, match):
    out = tmp_path / "o"
    assert_usage_error(_run(out, *argv_tail), capsys, match)
    assert not (out / RESULTS_FILE).exists() or not (out / RESULTS_FILE).read_bytes()


def test_unknown_suite(tmp_path, capsys):
    assert_usage_error(["run", "nope", "--out", str(tmp_path / "o")], capsys, "unknown suite 'nope'")


@pytest.mark.parametrize("out", ["", "  "])
def test_an_empty_out_is_refused_not_the_current_folder(tmp_path, capsys, monkeypatch, out):
    monkeypatch.chdir(tmp_path)
    assert_usage_error(_run(out), capsys, "--out")
    assert list(tmp_path.iterdir()) == []  # nothing written into the current folder


def test_out_is_a_file_or_under_one(afile, capsys):
    assert_usage_error(_run(afile), capsys, "exists and is not a folder")
    assert_usage_error(_run(afile / "sub" / "deeper"), capsys, "which is not a folder")
    assert afile.read_text() == "not a folder"


def test_out_not_writable(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)  # what a read-only folder says to non-root
    assert_usage_error(_run(tmp_path / "o"), capsys, "is not writable")


def test_out_that_cannot_be_created(tmp_path, capsys, monkeypatch):
    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", refuse)
    assert_usage_error(_run(tmp_path / "o"), capsys, "Permission denied")


def test_results_file_is_a_folder(finished, capsys):
    (finished / RESULTS_FILE).unlink()
    (finished / RESULTS_FILE).mkdir()
    assert_usage_error(_run(finished), capsys, "results.jsonl is a folder")
    assert_usage_error(["report", str(finished)], capsys, "results.jsonl is a folder")


@pytest.mark.parametrize("name", ["failures.jsonl", "discarded.jsonl", "summary.md", ".lock"])
def test_any_file_of_the_layout_as_a_folder_is_refused_before_running(finished, capsys, name):
    target = finished / name
    if target.exists():
        target.unlink()
    target.mkdir()
    assert_usage_error(_run(finished, "--seeds", "2"), capsys, f"{name} is a folder")


@pytest.mark.parametrize("content", ["[]", "garbage", "{}", '{"suite": 3}', '{"suite": "selftest", "sessions": 5}'])
def test_manifest_that_is_no_manifest(finished, capsys, content):
    (finished / MANIFEST_FILE).write_text(content)
    assert_usage_error(_run(finished), capsys, "manifest.json")
    assert_usage_error(["report", str(finished)], capsys, "manifest.json")
    assert (finished / MANIFEST_FILE).read_text() == content


def test_directory_of_another_suite(finished, capsys):
    assert_usage_error(["run", "ltl-translation", "--out", str(finished)], capsys, "holds results of suite 'selftest'")


def test_locked_directory(finished, capsys):
    with ResultStore(finished, "selftest"):
        assert_usage_error(_run(finished), capsys, "another steer-bench run is writing")


def test_ray_that_cannot_start(tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")

    def fail(*args, **kwargs):
        raise ConnectionError("could not start the\nraylet (simulated)")

    monkeypatch.setattr(ray, "init", fail)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    line = assert_usage_error(_run(tmp_path / "o", "--executor", "ray"), capsys, "cannot start a local Ray instance")
    assert "ConnectionError: could not start the raylet (simulated)" in line


def test_ray_cluster_that_does_not_answer_fails_fast(tmp_path, capsys):
    pytest.importorskip("ray")
    assert_usage_error(
        _run(tmp_path / "o", "--executor", "ray", "--address", "127.0.0.1:1"), capsys, "cannot reach the Ray cluster"
    )


def test_ray_missing(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    assert_usage_error(_run(tmp_path / "o", "--executor", "ray"), capsys, 'pip install "steer-envs[ray]"')


@pytest.mark.parametrize(
    ("source", "match"),
    [
        ("raise RuntimeError('boom at import')", "RuntimeError: boom at import"),
        ("def broken(:\n    pass", "SyntaxError"),
        ("import no_such_dependency_xyz", "ModuleNotFoundError"),
        (
            "from steer_envs.bench.suite import Suite, Metric, register_suite\n"
            "register_suite(Suite('bad suite', 'x', (Metric('m'),)))",
            "Suite.name must be a non-empty string without spaces",
        ),
    ],
)
def test_a_plugin_that_fails_to_import(tmp_path, capsys, monkeypatch, source, match):
    name = f"steer_bench_broken_{abs(hash(source)) % 10**8}"
    (tmp_path / f"{name}.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    for argv in (["list", "--plugin", name], _run(tmp_path / "o", "--plugin", name),
                 ["report", str(tmp_path), "--plugin", name]):  # fmt: skip
        line = assert_usage_error(argv, capsys, f"cannot import steer-bench plugin module {name!r}")
        assert match in line


# ------------------------------------------------------------------------------------- list
def test_list_errors(capsys):
    assert_usage_error(["list", "nope"], capsys, "unknown suite 'nope'")
    assert_usage_error(["list", "--bogus"], capsys, "unrecognized arguments")
    assert_usage_error([], capsys, "the following arguments are required")
    assert_usage_error(["frobnicate"], capsys, "invalid choice")


# ------------------------------------------------------------------------------------- report
def test_report_errors(finished, afile, tmp_path, capsys):
    assert_usage_error(["report", str(tmp_path / "missing")], capsys, "no results directory")
    assert_usage_error(["report", str(afile)], capsys, "no results directory")
    assert_usage_error(["report", ""], capsys, "expected a folder path")
    assert_usage_error(["report", str(tmp_path)], capsys, "has no manifest.json")
    assert_usage_error(["report", str(finished), "--format", "xml"], capsys, "invalid choice: 'xml'")
    assert_usage_error(["report", str(finished), "--plots", "--plots-dir", str(afile)], capsys, "not a folder")
    assert_usage_error(["report", str(finished), "--plots", "--plots-dir", str(afile / "x")], capsys, "not a folder")
    assert_usage_error(["report", str(finished), "--plots", "--plots-dir", ""], capsys, "expected a folder path")
    assert afile.read_text() == "not a folder"


def test_argv_must_be_strings():
    with pytest.raises(TypeError, match="argv must be a list of strs"):
        main(["run", 3])  # type: ignore[list-item]


# ------------------------------------------------------------------------------------- class 2 through the CLI
def test_one_bad_record_blocks_neither_report_nor_run(finished, capsys):
    results = finished / RESULTS_FILE
    good = results.read_bytes()
    with results.open("ab") as fh:
        fh.write(b'{"key":"x"}\n')
    status, err = _exit_and_stderr(["report", str(finished), "--format", "csv"], capsys)
    assert status == 0 and "line 3: 'config' is missing" in err and "moves them to discarded.jsonl" in err
    assert results.read_bytes() == good + b'{"key":"x"}\n'  # report only reads
    status, err = _exit_and_stderr(_run(finished, "--seeds", "2"), capsys)
    assert status == 0, err
    assert "quarantined 1 line of results.jsonl in discarded.jsonl: line 3: 'config' is missing" in err
    assert "4 trials planned: 2 already done, 2 run now, 0 failed" in err
    assert results.read_bytes().startswith(good) and results.read_bytes().count(b"\n") == 4
    assert json.loads((finished / DISCARDED_FILE).read_text())["bytes"] == '{"key":"x"}'
    assert "quarantined" in (finished / "summary.md").read_text()  # the note is in the run's summary too


def test_cli_errors_in_a_subprocess_are_one_line_without_traceback(afile):
    done = run_cli(*_run(afile / "sub"))
    assert done.returncode == 2 and done.stderr.strip().count("\n") == 0 and "Traceback" not in done.stderr
