"""steer-bench command line: help, exit codes, run/report formats, plots, kill + resume."""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from bench_helpers import bench_env, run_cli

from steer_envs.bench.cli import main
from steer_envs.bench.store import RESULTS_FILE, read_jsonl

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("argv", [["--help"], ["list", "--help"], ["run", "--help"], ["report", "--help"]])
def test_help_everywhere(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    assert "usage: steer-bench" in capsys.readouterr().out


def test_list_shows_suites_and_envs(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in ("selftest:", "smoke:", "quick:", "tour of: ", "envs:", "steer_envs/SoupScoop-v0"):
        assert name in out
    tour = next(line for line in out.splitlines() if "tour of: " in line)
    assert "smoke" in tour.split("tour of: ", 1)[1].split(", ")  # other domains' suites join the tour too


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "nope"], "unknown suite 'nope'; known suites:"),
        (["run", "selftest", "--method", "zz"], "unknown method 'zz'"),
        (["run", "selftest", "--param", "speed=3"], "has no parameter 'speed'"),
        (["run", "selftest", "--param", "samples=abc"], "'samples' must be int"),
        (["run", "selftest", "--address", "auto"], "only used by the ray executor"),
        (["report", "/nonexistent/steer-bench-dir"], "no results directory"),
    ],
)
def test_bad_input_exits_2_with_a_clear_message(argv, message, tmp_path, capsys):
    if argv[0] == "run":
        argv = [*argv, "--out", str(tmp_path / "o"), "--no-progress"]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_usage_errors_from_argparse_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "selftest", "--seeds", "0"])
    assert exc.value.code == 2
    assert "positive integer" in capsys.readouterr().err


def test_ray_missing_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)
    assert main(["run", "selftest", "--executor", "ray", "--out", str(tmp_path), "--no-progress"]) == 2
    assert "pip install 'steer-envs[ray]'" in capsys.readouterr().err


def test_run_prints_table_then_report_formats_and_plots(tmp_path, capsys):
    out = tmp_path / "st"
    argv = ["run", "selftest", "--seeds", "2", "--trials", "400", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "| pi (ref)" in captured.out and "Δ pi" in captured.out and "3.1416" in captured.out
    assert "4 trials planned: 0 already done, 4 run now, 0 failed" in captured.err
    assert (out / "summary.md").read_text().startswith("# steer-bench selftest: 4 trials")

    assert main(["report", str(out), "--format", "csv"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    pi_rows = [r for r in rows if r["metric"] == "pi"]
    assert len(rows) == 6 and len(pi_rows) == 2 and {r["n"] for r in pi_rows} == {"2"}
    assert all(float(r["reference"]) == pytest.approx(3.14159265) for r in pi_rows)
    assert all(float(r["diff"]) == pytest.approx(float(r["mean"]) - float(r["reference"])) for r in pi_rows)

    assert main(["report", str(out), "--format", "json", "--plots"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert {r["method"] for r in data["rows"]} == {"mc", "stratified"}
    pngs = sorted(p.name for p in (out / "plots").iterdir())
    assert pngs == ["selftest_abs_error.png", "selftest_pi.png", "selftest_samples_per_s.png"]
    assert all((out / "plots" / p).read_bytes().startswith(PNG_MAGIC) for p in pngs)

    assert main(["report", str(out)]) == 0  # markdown is the default
    assert "## selftest" in capsys.readouterr().out


def test_failed_trials_exit_1(tmp_path, capsys):
    flag = tmp_path / "flag"
    flag.touch()
    argv = ["run", "toy", "--plugin", "steer_bench_testplugin", "--env", "toy/A-v0", "--out", str(tmp_path / "o"),
            "--param", f"fail_flag={flag}", "--no-progress"]  # fmt: skip
    assert main(argv) == 1
    assert "4 trial(s) failed" in capsys.readouterr().err
    flag.unlink()
    assert main(argv) == 0


def test_sigkill_mid_run_then_resume_gives_exactly_the_trial_set(tmp_path):
    out = tmp_path / "killed"
    argv = [sys.executable, "-m", "steer_envs.bench", "run", "toy", "--plugin", "steer_bench_testplugin",
            "--seeds", "5", "--param", "sleep=0.15", "--out", str(out), "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(argv, env=bench_env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    results = out / RESULTS_FILE
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if results.exists() and results.read_bytes().count(b"\n") >= 4:
            break
        if proc.poll() is not None:
            pytest.fail(f"run exited early: {proc.stderr.read().decode()}")
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    proc.stderr.close()
    before, _ = read_jsonl(results)
    assert 4 <= len(before) < 20, "the kill must land mid-run"
    with results.open("ab") as fh:  # and a writer killed in the middle of a line
        fh.write(b'{"key": "0123456789abcdef", "config": {"su')

    resumed = run_cli(*argv[3:])
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(before)} already done, {20 - len(before)} run now, 0 failed" in resumed.stderr
    assert "torn last line" in resumed.stderr
    lines = results.read_bytes().split(b"\n")
    assert lines[-1] == b"" and all(json.loads(line) for line in lines[:-1])  # every line parses
    after = [json.loads(line) for line in lines[:-1]]
    keys = [r["key"] for r in after]
    assert len(keys) == 20 == len(set(keys))
    expected = {(env, method, seed) for env in ("toy/A-v0", "toy/B-v0") for method in "ab" for seed in range(5)}
    assert {(r["config"]["env"], r["config"]["method"], r["seed"]) for r in after} == expected
    assert after[: len(before)] == before  # what was written before the kill is kept as is
    manifest = json.loads((out / "manifest.json").read_text())
    assert [s["skipped"] for s in manifest["sessions"]] == [0, len(before)]
