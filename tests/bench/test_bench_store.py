"""results.jsonl: safe appends, tolerant reads, quarantine of bad lines, locking, manifest and directory checks."""

from __future__ import annotations

import json
import os
import stat

import pytest

from steer_envs.bench.records import ResultsDirError, encode_record, read_jsonl, record_problem
from steer_envs.bench.store import (
    DISCARDED_FILE,
    MANIFEST_FILE,
    RESULTS_FILE,
    ResultStore,
    StoreLockedError,
    atomic_write_text,
    check_output_dir,
    load_results,
)
from steer_envs.bench.suite import Trial


def _rec(name: str, value: float = 1.0, *, suite: str = "s", seed: int = 0) -> dict:
    """A valid record of suite ``suite``: method ``name``, so the key is a function of the name."""
    trial = Trial(suite, None, name, seed, {}, "math:sqrt")
    return {"key": trial.key, "config": trial.config, "seed": seed, "metrics": {"v": value}}


def _key(name: str, **kw) -> str:
    return _rec(name, **kw)["key"]


def _discarded(path) -> list[dict]:
    return [json.loads(line) for line in (path / DISCARDED_FILE).read_text().splitlines()]


def test_append_then_read_roundtrip(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a", 1.5))
        store.append(_rec("b", 2.5))
        assert store.finished_keys == {_key("a"), _key("b")}
    raw = (tmp_path / RESULTS_FILE).read_bytes()
    assert raw.endswith(b"\n") and raw.count(b"\n") == 2
    records, report = read_jsonl(tmp_path / RESULTS_FILE)
    assert [r["metrics"]["v"] for r in records] == [1.5, 2.5]
    assert report.clean


def test_reader_ignores_torn_last_line_and_open_repairs_it(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a"))
    path = tmp_path / RESULTS_FILE
    torn = encode_record(_rec("b"))[:25]
    with path.open("ab") as fh:
        fh.write(torn)
    records, report = read_jsonl(path)
    assert [r["key"] for r in records] == [_key("a")]
    assert report.torn_tail == torn
    with ResultStore(tmp_path, "s") as store:
        assert store.finished_keys == {_key("a")}
        assert any("torn last line" in n for n in store.notes)
        store.append(_rec("b"))
    records, report = read_jsonl(path)
    assert [r["key"] for r in records] == [_key("a"), _key("b")] and report.clean
    assert _discarded(tmp_path)[0]["bytes"] == torn.decode()


def test_file_without_any_newline_is_all_torn(tmp_path):
    path = tmp_path / RESULTS_FILE
    path.write_bytes(b'{"key": "a", "metr')
    records, report = read_jsonl(path)
    assert records == [] and report.torn_tail


def test_corrupt_middle_line_and_duplicates_are_dropped(tmp_path):
    path = tmp_path / RESULTS_FILE
    path.write_bytes(encode_record(_rec("a")) + b"garbage\n" + b"[1, 2]\n" + encode_record(_rec("a", 9.0)))
    records, report = read_jsonl(path)
    assert [r["metrics"]["v"] for r in records] == [1.0]
    assert report.corrupt_lines == [2, 3] and report.duplicates == 1


def test_append_rejects_duplicates_nan_and_invalid_records(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a"))
        with pytest.raises(ValueError, match="already recorded"):
            store.append(_rec("a"))
        with pytest.raises(ValueError, match="NaN"):
            store.append(_rec("b", float("nan")))
        with pytest.raises(ValueError, match="'config' is missing"):
            store.append({"metrics": {}})
        with pytest.raises(ValueError, match="does not match its config"):
            store.append({**_rec("c"), "key": "0" * 20})
        with pytest.raises(ValueError, match="does not belong"):
            store.append(_rec("d", suite="other"))
    assert len(read_jsonl(tmp_path / RESULTS_FILE)[0]) == 1


def test_second_writer_is_locked_out(tmp_path):
    with ResultStore(tmp_path, "s"):
        with pytest.raises(StoreLockedError, match="another steer-bench run"):
            ResultStore(tmp_path, "s").open()
    with ResultStore(tmp_path, "s"):  # released on close
        pass


def test_directory_of_another_suite_is_refused(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.start_session({"argv": []})
    with pytest.raises(ValueError, match="holds results of suite 's'"):
        ResultStore(tmp_path, "other").open()
    manifest, records, _ = load_results(tmp_path)
    assert manifest["suite"] == "s" and len(manifest["sessions"]) == 1 and records == []


def test_load_results_needs_a_results_directory(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_results(tmp_path / "missing")
    with pytest.raises(FileNotFoundError, match="manifest"):
        load_results(tmp_path)


def test_atomic_write_replaces_whole_file(tmp_path):
    target = tmp_path / "x" / "f.txt"
    atomic_write_text(target, "one")
    atomic_write_text(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["f.txt"]  # no temp files left


# ----------------------------------------------------------------- issue class 2: one bad record blocks nothing
BAD_RECORDS = [
    {"key": "x"},
    {"key": "x", "config": {"suite": "s", "env": None, "method": "a", "params": {}}, "seed": 0, "metrics": {}},
    {**_rec("w"), "seed": "0"},
    {**_rec("w"), "metrics": {"v": "1.0"}},
    {**_rec("w"), "metrics": [1.0]},
    {**_rec("w"), "config": {"suite": "s"}},
    {**_rec("w"), "extra": [1, 2]},
    {**_rec("w"), "schema": 99},
    {**_rec("w"), "metrics": {"v": float("nan")}},
    {**_rec("w"), "extra": {"x": float("inf")}},  # json.dumps writes Infinity: not strict JSON
    _rec("w", suite="foreign"),
    [1, 2, 3],
    "just a string",
    None,
]


@pytest.mark.parametrize("bad", BAD_RECORDS, ids=range(len(BAD_RECORDS)))
def test_valid_json_that_is_no_record_is_quarantined_and_good_lines_kept(tmp_path, bad):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a"))
        store.append(_rec("b"))
    path = tmp_path / RESULTS_FILE
    good = path.read_bytes()
    bad_line = json.dumps(bad).encode()
    with path.open("ab") as fh:
        fh.write(bad_line + b"\n")
    foreign = isinstance(bad, dict) and bad.get("config", {}).get("suite") == "foreign"
    if not foreign:  # an unregistered suite's directory cannot tell foreign records (see the next test)
        _, records, report = load_results(tmp_path)  # what `report` reads: the good ones, the bad one listed
        assert [r["key"] for r in records] == [_key("a"), _key("b")]
        assert report.corrupt_lines == [3] and report.describe()
    with ResultStore(tmp_path, "s") as store:  # what `run` does: quarantine, then go on
        assert store.finished_keys == {_key("a"), _key("b")}
        assert len(store.notes) == 1 and "quarantined 1 line" in store.notes[0]
        store.append(_rec("c"))
    assert path.read_bytes() == good + encode_record(_rec("c"))  # the good lines, byte for byte
    (entry,) = _discarded(tmp_path)
    assert entry["bytes"] == bad_line.decode() and entry["line"] == 3 and entry["reason"]
    assert load_results(tmp_path)[2].clean


def test_a_bad_line_in_the_middle_keeps_both_neighbours(tmp_path):
    path = tmp_path / RESULTS_FILE
    with ResultStore(tmp_path, "s"):
        pass
    path.write_bytes(encode_record(_rec("a")) + b'{"key":"x"}\n\x80abc\n' + encode_record(_rec("b")))
    with ResultStore(tmp_path, "s") as store:
        assert store.finished_keys == {_key("a"), _key("b")}
    assert path.read_bytes() == encode_record(_rec("a")) + encode_record(_rec("b"))
    entries = _discarded(tmp_path)
    assert [e["line"] for e in entries] == [2, 3]
    assert "base64" in entries[1] and "not UTF-8" in entries[1]["reason"]


def test_report_of_a_registered_suite_skips_foreign_records(tmp_path):
    with ResultStore(tmp_path, "selftest") as store:
        store.append(_rec("mc", suite="selftest"))
    with (tmp_path / RESULTS_FILE).open("ab") as fh:
        fh.write(encode_record(_rec("mc", suite="smoke")))
    _, records, report = load_results(tmp_path)
    assert len(records) == 1 and "suite 'smoke', which does not belong" in report.bad_lines[0].reason


def test_a_valid_last_line_without_newline_is_a_finished_trial(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a"))
    path = tmp_path / RESULTS_FILE
    with path.open("ab") as fh:
        fh.write(encode_record(_rec("b"))[:-1])  # killed after the record, before its newline
    records, report = read_jsonl(path)
    assert [r["key"] for r in records] == [_key("a"), _key("b")] and report.missing_newline
    with ResultStore(tmp_path, "s") as store:
        assert store.finished_keys == {_key("a"), _key("b")}
        assert any("newline appended" in n for n in store.notes)
        store.append(_rec("c"))
    assert path.read_bytes() == b"".join(encode_record(_rec(n)) for n in "abc")
    assert not (tmp_path / DISCARDED_FILE).exists()


def test_duplicates_are_quarantined_not_lost(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a", 1.0))
    path = tmp_path / RESULTS_FILE
    with path.open("ab") as fh:
        fh.write(encode_record(_rec("a", 2.0)))
    with ResultStore(tmp_path, "s") as store:
        assert [r["metrics"]["v"] for r in store.records] == [1.0]
    (entry,) = _discarded(tmp_path)
    assert "duplicate of line 1" in entry["reason"] and json.loads(entry["bytes"])["metrics"]["v"] == 2.0


def test_record_problem_names_what_is_wrong():
    assert record_problem(_rec("a")) is None
    assert record_problem({**_rec("a"), "metrics": {"v": float("nan")}}).startswith("metric 'v' must be a finite")
    assert record_problem({**_rec("a"), "seed": True}) == "'seed' must be an int, got bool True"
    assert "does not belong" in record_problem(_rec("a"), accepts_suite=lambda s: s == "t")
    assert record_problem({"config": {}}) == "'config.suite' is missing"


# ----------------------------------------------------------------- issue class 5: unusable directories
def test_directory_problems_are_results_dir_errors(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(ResultsDirError, match=r"lies under .*afile, which is not a folder"):
        ResultStore(afile / "sub", "s").open()
    with pytest.raises(ResultsDirError, match="exists and is not a folder"):
        ResultStore(afile, "s").open()
    with pytest.raises(ResultsDirError, match="must not be empty"):
        ResultStore("", "s")
    with pytest.raises(TypeError, match=r"str or os\.PathLike"):
        check_output_dir(3)
    as_dir = tmp_path / "d1"
    (as_dir / RESULTS_FILE).mkdir(parents=True)
    (as_dir / MANIFEST_FILE).write_text(json.dumps({"suite": "s"}))
    with pytest.raises(ResultsDirError, match=r"results\.jsonl is a folder"):
        ResultStore(as_dir, "s").open()
    with pytest.raises(ResultsDirError, match=r"results\.jsonl is a folder"):
        load_results(as_dir)


@pytest.mark.parametrize("content", [b"[]", b"garbage", b'{"sessions": []}', b'{"suite": 3}', b"\xff", b"[" * 100_000])
def test_a_manifest_that_is_no_manifest_is_refused(tmp_path, content):
    (tmp_path / MANIFEST_FILE).write_bytes(content)
    with pytest.raises(ResultsDirError, match=r"manifest\.json"):
        ResultStore(tmp_path, "s").open()
    with pytest.raises(ResultsDirError, match=r"manifest\.json"):
        load_results(tmp_path)
    assert (tmp_path / MANIFEST_FILE).read_bytes() == content  # never overwritten


def test_a_fifo_as_results_file_is_refused_not_read(tmp_path):
    with ResultStore(tmp_path, "s"):
        pass
    (tmp_path / RESULTS_FILE).unlink()
    os.mkfifo(tmp_path / RESULTS_FILE)  # reading it would block forever
    with pytest.raises(ResultsDirError, match="FIFO"):
        ResultStore(tmp_path, "s").open()
    with pytest.raises(ResultsDirError, match="FIFO"):
        load_results(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_an_unwritable_directory_is_refused(tmp_path):
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with pytest.raises(ResultsDirError, match="not writable"):
            ResultStore(locked / "out", "s").open()
    finally:
        locked.chmod(0o755)


def test_new_files_get_normal_modes(tmp_path):
    umask = os.umask(0o022)
    try:
        with ResultStore(tmp_path / "o", "s") as store:
            store.append(_rec("a"))
            store.append_failure({"key": "k"})
    finally:
        os.umask(umask)
    for name in (RESULTS_FILE, MANIFEST_FILE, "failures.jsonl"):
        assert stat.S_IMODE((tmp_path / "o" / name).stat().st_mode) == 0o644, name
