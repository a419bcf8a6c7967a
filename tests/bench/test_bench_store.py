"""results.jsonl: safe appends, tolerant reads, repair of torn tails, locking, manifest checks."""

from __future__ import annotations

import json

import pytest

from steer_envs.bench.store import (
    DISCARDED_FILE,
    RESULTS_FILE,
    ResultStore,
    StoreLockedError,
    atomic_write_text,
    encode_record,
    load_results,
    read_jsonl,
)


def _rec(key: str, value: float = 1.0) -> dict:
    return {"key": key, "config": {"suite": "s", "env": None, "method": None, "params": {}}, "seed": 0,
            "metrics": {"v": value}}  # fmt: skip


def test_append_then_read_roundtrip(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a", 1.5))
        store.append(_rec("b", 2.5))
        assert store.finished_keys == {"a", "b"}
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
    assert [r["key"] for r in records] == ["a"]
    assert report.torn_tail == torn
    with ResultStore(tmp_path, "s") as store:
        assert store.finished_keys == {"a"}
        assert any("torn last line" in n for n in store.notes)
        store.append(_rec("b"))
    records, report = read_jsonl(path)
    assert [r["key"] for r in records] == ["a", "b"] and report.clean
    discarded = [json.loads(line) for line in (tmp_path / DISCARDED_FILE).read_text().splitlines()]
    assert discarded[0]["bytes"] == torn.decode()


def test_file_without_any_newline_is_all_torn(tmp_path):
    path = tmp_path / RESULTS_FILE
    path.write_bytes(b'{"key": "a", "metr')
    records, report = read_jsonl(path)
    assert records == [] and report.torn_tail


def test_corrupt_middle_line_and_duplicates_are_dropped(tmp_path):
    path = tmp_path / RESULTS_FILE
    path.write_bytes(encode_record(_rec("a")) + b"garbage\n" + b"[1, 2]\n" + encode_record(_rec("a", 9.0)))
    records, report = read_jsonl(path)
    assert [(r["key"], r["metrics"]["v"]) for r in records] == [("a", 1.0)]
    assert report.corrupt_lines == [2, 3] and report.duplicates == 1


def test_append_rejects_duplicates_nan_and_missing_key(tmp_path):
    with ResultStore(tmp_path, "s") as store:
        store.append(_rec("a"))
        with pytest.raises(ValueError, match="already recorded"):
            store.append(_rec("a"))
        with pytest.raises(ValueError, match="NaN"):
            store.append(_rec("b", float("nan")))
        with pytest.raises(ValueError, match="key"):
            store.append({"metrics": {}})
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
