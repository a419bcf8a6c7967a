"""One cache of data shards: files built once from their settings, reused while they read back, merged on demand.

A *shard* is the unit of work of a data-generation job (one episode seed, one
demonstration): a list of records built by a function of its settings and
written atomically (the record format's ``save``, e.g. through
:func:`steer_envs.io.atomic_write_npz`) under ``<cache folder>/shards/<file name>``,
the file name hashing whatever the contents depend on. :class:`ShardCache`
reads a shard back with the format's ``load`` (which raises
:class:`~steer_envs.io.DatasetError` naming the file for a damaged file) and
treats a file that does not read back (missing, torn, an older format) as not
built: it is built again. So a job resumes where it stopped, runs shards in
parallel processes (each writes its own file), and a merged file of many
shards (:meth:`ShardCache.merged`) is written once beside them.

Builders that need a simulator share one per process with :class:`LazyEnvs`
(made on first use, one per key, closed together).

:func:`default_cache_dir` is the one rule for where caches live:
``$XDG_CACHE_HOME/steer-envs/<name>`` (``~/.cache/steer-envs/<name>`` when the
variable is unset or empty).

>>> import json, tempfile
>>> from pathlib import Path
>>> def save(path, records, meta):
...     path.parent.mkdir(parents=True, exist_ok=True)
...     path.write_text(json.dumps({"records": list(records), "meta": meta}))
...     return path
>>> cache = ShardCache(
...     Path(tempfile.mkdtemp()),
...     name=lambda seed: f"squares-{seed}.json",
...     build=lambda seed: [seed * seed],
...     load=lambda path: json.loads(path.read_text())["records"],
...     save=save,
... )
>>> cache.ensure(3)[0], cache.ensure(3)[2]  # built once, then found
([9], False)
>>> cache.merged("all.json", range(4), {"n": 4})[0]
[0, 1, 4, 9]
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, is_dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from steer_envs.io import DatasetError

__all__ = [
    "LazyEnvs",
    "ShardCache",
    "plan_set_args",
    "plan_set_parser",
    "shard_file",
    "shard_meta",
]

S = TypeVar("S")
R = TypeVar("R")
E = TypeVar("E")
K = TypeVar("K", bound=Hashable)


def shard_file(folder: str | os.PathLike[str], file_name: str) -> Path:
    """Where a shard named ``file_name`` of the cache ``folder`` lives: ``folder/shards/file_name``."""
    return Path(folder) / "shards" / file_name


def shard_meta(settings: Any) -> dict[str, Any]:
    """What a shard stores beside its records by default: ``{"shard": its settings}`` (a dataclass as a dict)."""
    return {"shard": asdict(settings) if is_dataclass(settings) and not isinstance(settings, type) else settings}


@dataclass(frozen=True)
class ShardCache(Generic[S, R]):
    """Shards of records ``R``, one file per settings ``S``, under ``folder / "shards"`` (module docstring).

    Attributes:
        folder: the cache folder (shards in its ``shards`` subfolder, merged files in it).
        name: the file name of a settings' shard (hashing what its contents depend on).
        build: the records of a settings' shard (called only for a shard not on disk).
        load: reads a file back; :class:`~steer_envs.io.DatasetError` when it cannot.
        save: ``save(path, records, meta)`` writes a file atomically and returns its path.
        meta: what a shard stores beside its records (default :func:`shard_meta`).
    """

    folder: Path
    name: Callable[[S], str]
    build: Callable[[S], Sequence[R]]
    load: Callable[[Path], Sequence[R]]
    save: Callable[[Path, Sequence[R], Mapping[str, Any]], Any]
    meta: Callable[[S], Mapping[str, Any]] = field(default=shard_meta)

    def path(self, settings: S) -> Path:
        """Where the shard of ``settings`` lives (:func:`shard_file`)."""
        return shard_file(self.folder, self.name(settings))

    def read(self, path: str | os.PathLike[str]) -> list[R] | None:
        """The records of ``path``, or ``None`` when there is no readable file (missing, torn, an older format)."""
        src = Path(path)
        if not src.exists():
            return None
        try:
            return list(self.load(src))
        except DatasetError:
            return None

    def ensure(self, settings: S) -> tuple[list[R], Path, bool]:
        """The shard ``(records, file, built now)``: read back, or built and written atomically."""
        path = self.path(settings)
        found = self.read(path)
        if found is not None:
            return found, path, False
        records = list(self.build(settings))
        self.save(path, records, self.meta(settings))
        return records, path, True

    def gather(self, settings: Iterable[S]) -> list[R]:
        """Every record of the shards of ``settings``, in their order (missing shards built here)."""
        out: list[R] = []
        for item in settings:
            out += self.ensure(item)[0]
        return out

    def merged(self, file_name: str, settings: Iterable[S], meta: Mapping[str, Any]) -> tuple[list[R], Path]:
        """``folder / file_name``: the records of every shard of ``settings`` in one file, written once.

        A readable merged file is reused as it is; else the shards are gathered
        (:meth:`gather`) and written to it atomically with ``meta``.
        """
        path = Path(self.folder) / file_name
        found = self.read(path)
        if found is not None:
            return found, path
        records = self.gather(settings)
        self.save(path, records, meta)
        return records, path


class LazyEnvs(Generic[K, E]):
    """One env per key, made by ``make(key)`` on first use and kept until :meth:`close` (or the ``with`` block's end).

    Building a robosuite env takes seconds: a process that builds many shards
    keeps its envs here.

    >>> made = []
    >>> with LazyEnvs(lambda key: made.append(key) or {"task": key}) as envs:
    ...     _ = envs.get("sink"), envs.get("sink"), envs.get("microwave")
    >>> made
    ['sink', 'microwave']
    """

    def __init__(self, make: Callable[[K], E]) -> None:
        self._make = make
        self._envs: dict[K, E] = {}

    def get(self, key: K) -> E:
        """The env of ``key`` (made now on first use)."""
        if key not in self._envs:
            self._envs[key] = self._make(key)
        return self._envs[key]

    def close(self) -> None:
        """Close (those with a ``close`` method) and forget every env made so far."""
        while self._envs:
            env = self._envs.popitem()[1]
            close = getattr(env, "close", None)
            if callable(close):
                close()

    def __enter__(self) -> LazyEnvs[K, E]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def plan_set_parser(module: str, domain: str, suite: str, episodes: int) -> argparse.ArgumentParser:
    """The parser of ``python -m steer_envs.data.<module>``, which writes ``domain``'s skill-plan data set from
    the ``suite``'s shards: ``--cache-dir`` and ``--episodes`` (default ``episodes``).

    The domain adds its own options; :func:`plan_set_args` adds ``--out`` and parses.
    """
    parser = argparse.ArgumentParser(
        prog=f"python -m steer_envs.data.{module}",
        description=f"Write the {domain} skill-plan data set (one plan per successful skill) from the {suite} "
        f"shards; build the shards first in parallel with `steer-bench run {suite} --seeds N --workers 2 "
        "--param cache_dir=DIR`.",
    )
    parser.add_argument("--cache-dir", required=True, help="the shards' cache folder (the suite's cache_dir)")
    parser.add_argument("--episodes", type=int, default=episodes, help=f"episode seeds 0..N-1 (default {episodes})")
    return parser


def plan_set_args(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """``argv`` parsed by ``parser`` (:func:`plan_set_parser`) with ``--out`` (a ``.npz``; exit 2 otherwise)."""
    parser.add_argument("--out", required=True, help="output .npz (a steer_envs.data.trajectories file)")
    args = parser.parse_args(argv)
    if not str(args.out).endswith(".npz"):
        parser.error(f"--out must end with .npz, got {args.out!r}")
    return args
