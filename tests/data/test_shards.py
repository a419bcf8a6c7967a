"""The one shard cache: built once, found again, rebuilt when torn, merged once; the cache-folder rule."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from steer_envs.data.shards import LazyEnvs, ShardCache, shard_file, shard_meta
from steer_envs.io import DatasetError, atomic_write_text, default_cache_dir


def _load(path: Path) -> list[int]:
    try:
        return list(json.loads(path.read_text())["records"])
    except (ValueError, KeyError) as err:
        raise DatasetError(f"{path}: not a shard ({err})") from None


def _save(path: Path, records: Sequence[int], meta: Mapping[str, Any]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps({"records": list(records), "meta": dict(meta)}))
    return path


def _cache(folder: Path, built: list[int]) -> ShardCache[int, int]:
    def build(seed: int) -> list[int]:
        built.append(seed)
        return [seed, seed * seed]

    return ShardCache(folder, name=lambda seed: f"sq-{seed}.json", build=build, load=_load, save=_save)


def test_a_shard_is_built_once_and_a_torn_one_again(tmp_path: Path) -> None:
    built: list[int] = []
    cache = _cache(tmp_path, built)
    records, path, made = cache.ensure(3)
    assert (records, made, built) == ([3, 9], True, [3])
    assert path == shard_file(tmp_path, "sq-3.json") == tmp_path / "shards" / "sq-3.json"
    assert json.loads(path.read_text())["meta"] == {"shard": 3}
    assert cache.ensure(3) == ([3, 9], path, False) and built == [3]
    path.write_text("{torn")  # a file that does not read back is not built
    assert cache.ensure(3)[2] is True and built == [3, 3]


def test_merged_reads_every_shard_in_order_and_is_written_once(tmp_path: Path) -> None:
    built: list[int] = []
    cache = _cache(tmp_path, built)
    cache.ensure(1)
    records, merged = cache.merged("all.json", [0, 1, 2], {"n": 3})
    assert records == [0, 0, 1, 1, 2, 4] and built == [1, 0, 2] and merged == tmp_path / "all.json"
    assert json.loads(merged.read_text())["meta"] == {"n": 3}
    assert cache.merged("all.json", [0, 1, 2], {"n": 3}) == (records, merged) and built == [1, 0, 2]
    assert cache.gather([2, 0]) == [2, 4, 0, 0]


def test_default_cache_dir_follows_xdg_cache_home(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", "/tmp/xdg")
    assert default_cache_dir("itps-kitchen") == Path("/tmp/xdg/steer-envs/itps-kitchen")
    monkeypatch.setenv("XDG_CACHE_HOME", "")
    assert default_cache_dir("sb3") == Path.home() / ".cache" / "steer-envs" / "sb3"
    for bad in ("", "..", "a/b", 3):
        with pytest.raises(ValueError, match="one folder name"):
            default_cache_dir(bad)  # type: ignore[arg-type]


def test_lazy_envs_make_one_env_per_key_and_close_them_all() -> None:
    closed: list[str] = []

    class Env:
        def __init__(self, key: str) -> None:
            self.key = key

        def close(self) -> None:
            closed.append(self.key)

    envs: LazyEnvs[str, Env] = LazyEnvs(Env)
    assert envs.get("a") is envs.get("a") and envs.get("b").key == "b"
    envs.close()
    assert sorted(closed) == ["a", "b"]
    assert envs.get("a").key == "a" and len(closed) == 2  # a fresh one after close


def test_shard_meta_stores_dataclass_settings_as_dicts() -> None:
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Settings:
        seed: int
        task: str

    assert shard_meta(Settings(2, "sink")) == {"shard": {"seed": 2, "task": "sink"}}
