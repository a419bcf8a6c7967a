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
from steer_envs.bench.records import read_jsonl
from steer_envs.bench.store import RESULTS_FILE

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
    assert 'pip install "steer-envs[ray]"' in capsys.readouterr().err


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


# ------------------------------------------------------------------------------- resume UX: all done, --fresh
def _selftest(out, *extra):
    return ["run", "selftest", "--seeds", "2", "--trials", "400", "--out", str(out), "--no-progress", *extra]


def test_all_done_says_so_prints_the_report_and_starts_no_executor(tmp_path, monkeypatch, capsys):
    import types

    from steer_envs.bench import executors

    out = tmp_path / "st"
    assert main(_selftest(out)) == 0
    first = capsys.readouterr().out

    def boom(self):
        raise AssertionError(f"{type(self).__name__} started with nothing to run")

    monkeypatch.setattr(executors.ProcessPoolExecutor, "start", boom)
    monkeypatch.setattr(executors.RayExecutor, "start", boom)
    fake_ray = types.SimpleNamespace(is_initialized=lambda: False, init=boom, shutdown=boom)
    monkeypatch.setitem(sys.modules, "ray", fake_ray)
    for extra in ([], ["--workers", "2"], ["--executor", "ray"]):
        assert main(_selftest(out, *extra)) == 0
        captured = capsys.readouterr()
        assert f"all 4 trials already done in {out}; nothing was run (--fresh starts over)" in captured.err
        assert "run now" not in captured.err
        assert captured.out == first  # the same report as the run that did the work
    manifest = json.loads((out / "manifest.json").read_text())
    assert [s["skipped"] for s in manifest["sessions"]] == [0, 4, 4, 4]


def test_fresh_moves_the_earlier_results_aside_and_deletes_nothing(tmp_path, capsys):
    out = tmp_path / "st"
    assert main(_selftest(out)) == 0
    (out / "plots").mkdir()
    (out / "plots" / "mine.png").write_bytes(PNG_MAGIC)
    (out / "notes.txt").write_text("my notes")
    earlier = {name: (out / name).read_bytes() for name in ("results.jsonl", "manifest.json", "summary.md")}
    capsys.readouterr()

    assert main(_selftest(out, "--fresh")) == 0
    err = capsys.readouterr().err
    (previous,) = (out / "previous").iterdir()
    assert f"started over (fresh): moved the earlier results (4 trials; results.jsonl, summary.md, plots, " \
           f"manifest.json) to {previous}; nothing was deleted" in err  # fmt: skip
    assert "4 trials planned: 0 already done, 4 run now, 0 failed" in err
    assert {name: (previous / name).read_bytes() for name in earlier} == earlier
    assert (previous / "plots" / "mine.png").read_bytes() == PNG_MAGIC
    assert (out / "notes.txt").read_text() == "my notes"  # not steer-bench's: left where it was
    assert not (out / "plots").exists()
    assert len(read_jsonl(out / RESULTS_FILE)[0]) == 4
    assert len(json.loads((out / "manifest.json").read_text())["sessions"]) == 1
    assert main(["report", str(previous), "--format", "json"]) == 0  # the earlier results are a directory of their own
    assert json.loads(capsys.readouterr().out)["rows"]

    assert main(_selftest(out, "--fresh")) == 0  # again: a second folder beside the first
    assert len(list((out / "previous").iterdir())) == 2


def test_fresh_on_a_new_folder_runs_and_on_another_suite_refuses(tmp_path, capsys):
    new = tmp_path / "new"
    assert main(_selftest(new, "--fresh")) == 0
    assert not (new / "previous").exists() and "started over" not in capsys.readouterr().err
    other = tmp_path / "toy"
    argv = ["run", "toy", "--plugin", "steer_bench_testplugin", "--env", "toy/A-v0", "--seeds", "1"]
    assert main([*argv, "--out", str(other), "--no-progress"]) == 0
    before = sorted(p.name for p in other.iterdir())
    capsys.readouterr()
    assert main(_selftest(other, "--fresh")) == 2
    assert "holds results of suite 'toy', not 'selftest'; choose another --out" in capsys.readouterr().err
    assert sorted(p.name for p in other.iterdir()) == before  # nothing moved


def test_run_help_explains_fresh_and_progress(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--fresh" in text and "moved to DIR/previous/<UTC time>/ (nothing is deleted; other files stay)" in text
    assert "--progress, --no-progress" in text and "shown only when stderr is a terminal" in text


def test_progress_bar_only_on_a_terminal_unless_asked(tmp_path, capsys):
    argv = ["run", "selftest", "--seeds", "1", "--trials", "100"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0  # stderr is no terminal under pytest
    assert "%|" not in capsys.readouterr().err
    assert main([*argv, "--out", str(tmp_path / "b"), "--progress"]) == 0
    assert "selftest: 100%|" in capsys.readouterr().err
