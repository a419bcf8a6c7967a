"""Minari datasets on disk: where they live, valid ids, and storing episodes as a dataset atomically.

:func:`store_minari_dataset` writes episodes (plain arrays) as a local
`Minari <https://minari.farama.org>`_ dataset: built in a temp folder next to
its final place and renamed there when complete
(:func:`steer_envs.io.atomic_directory`), so a killed export leaves no dataset
(its leftovers are removed by the next export into the same folder). It needs
the ``minari`` extra (:func:`require_minari`). :func:`minari_root` is Minari's
own data path, :func:`minari_load_command` the shell line that loads a
dataset stored elsewhere. The Maze2D random walk's export
(:func:`steer_envs.data.maze_random_walk.to_minari`) is built on these.

>>> check_minari_id("steer/maze2d-umaze-v0")
'steer/maze2d-umaze-v0'
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

from steer_envs.core.extras import MissingExtraError, install_command, missing_modules, require
from steer_envs.io import atomic_directory

__all__ = ["check_minari_id", "minari_load_command", "minari_root", "require_minari", "store_minari_dataset"]

#: the environment variable that names Minari's data path
_PATH_VARIABLE = "MINARI_DATASETS_PATH"


def minari_root() -> Path:
    """The folder Minari keeps local datasets in: ``MINARI_DATASETS_PATH``, else ``~/.minari/datasets`` (absolute)."""
    root = os.environ.get(_PATH_VARIABLE)
    return Path(os.path.abspath(os.path.expanduser(root))) if root else Path.home() / ".minari" / "datasets"


def check_minari_id(dataset_id: Any) -> str:
    """``dataset_id`` if it is a Minari id such as ``"steer/maze2d-large-v0"`` (a relative path of plain names).

    ``ValueError`` otherwise (empty, leading or trailing ``/``, ``.`` or ``..`` parts, other characters).
    """
    if not isinstance(dataset_id, str) or not dataset_id or dataset_id != dataset_id.strip("/"):
        raise ValueError(f"dataset_id must be a Minari id such as 'steer/maze2d-large-v0', got {dataset_id!r}")
    parts = dataset_id.split("/")
    if any(part in ("", ".", "..") for part in parts) or not re.fullmatch(r"[A-Za-z0-9_.\-/]+", dataset_id):
        raise ValueError(f"dataset_id must be a Minari id such as 'steer/maze2d-large-v0', got {dataset_id!r}")
    return dataset_id


def require_minari(feature: str) -> ModuleType:
    """The ``minari`` module, or :class:`~steer_envs.core.extras.MissingExtraError` naming ``feature`` and the
    ``minari`` extra when Minari or a storage backend for it (h5py or pyarrow) is not installed."""
    minari = require("minari", "minari", feature)
    if missing_modules("h5py") and missing_modules("pyarrow"):
        raise MissingExtraError(
            f"{feature} needs a Minari storage backend (h5py): {install_command('minari')}", name="h5py", extra="minari"
        )
    return minari


def _torn_minari_export(folder: Path) -> bool:
    """Whether ``folder`` is what a killed export of an earlier version left: our dataset, with no episodes."""
    meta_file = folder / "data" / "metadata.json"
    try:
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return not any(folder.rglob("*.hdf5"))  # not even metadata: nothing of value
    if not isinstance(meta, dict):
        return False
    authors = meta.get("author")
    authors = [authors] if isinstance(authors, str) else authors if isinstance(authors, list) else []
    ours = not authors or any(str(a).startswith("steer-envs") for a in authors)
    return ours and not meta.get("total_episodes")


def _final_folder(dataset_id: str, root: str | os.PathLike[str] | None) -> tuple[Path, Path, bool]:
    """The data path, the dataset's folder in it, and whether a torn dataset there is to be replaced.

    ``FileExistsError`` when a complete dataset of that id is there.
    """
    # absolute from here on: Minari joins its data path with the id itself, and a relative path taken
    # once from the working directory and once from the temp folder would double the path
    base = minari_root() if root is None else Path(os.path.abspath(os.path.expanduser(os.fspath(root))))
    final = base.joinpath(*dataset_id.split("/"))
    if not final.exists():
        return base, final, False
    if not (final.is_dir() and _torn_minari_export(final)):
        raise FileExistsError(f"a Minari dataset {dataset_id!r} already exists at {final}; use another id or version")
    return base, final, True


def store_minari_dataset(
    dataset_id: str,
    episodes: Sequence[Mapping[str, Any]],
    *,
    env_id: str,
    env_kwargs: Mapping[str, Any],
    root: str | os.PathLike[str] | None,
    algorithm_name: str,
    author: str,
    description: str,
) -> Any:
    """Store ``episodes`` as the local Minari dataset ``dataset_id`` under ``root`` atomically; returns it.

    ``episodes``: per episode the keyword arguments of Minari's ``EpisodeBuffer``
    besides its ``id`` (``observations``, ``actions``, ``rewards``,
    ``terminations``, ``truncations``, ``infos``). ``root`` (a relative path is
    taken from the working directory) defaults to :func:`minari_root`, where
    ``minari.load_dataset(dataset_id)`` finds it; for another ``root``, load
    with ``MINARI_DATASETS_PATH=<root>``. The dataset's env is
    ``gymnasium.make(env_id, **env_kwargs)``.

    An existing complete dataset of that id is refused (``FileExistsError``), a
    torn one left by a killed export of an earlier version (no episodes) is
    replaced. ``MINARI_DATASETS_PATH`` is the same after the call as before.
    """
    minari = require_minari("store_minari_dataset")
    import gymnasium as gym
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage
    from minari.namespace import create_namespace, list_local_namespaces

    base, final, overwrite = _final_folder(dataset_id, root)
    namespace = dataset_id.rsplit("/", 1)[0] if "/" in dataset_id else None
    buffers = [EpisodeBuffer(id=k, **episode) for k, episode in enumerate(episodes)]
    env = gym.make(env_id, **env_kwargs)
    try:
        with _data_path_restored():
            if namespace is not None:
                os.environ[_PATH_VARIABLE] = str(base)
                if namespace not in list_local_namespaces():
                    create_namespace(namespace)
            with atomic_directory(final, overwrite=overwrite) as build:
                scratch = build.absolute() / "_minari"
                os.environ[_PATH_VARIABLE] = str(scratch)
                with warnings.catch_warnings():  # Minari recommends author/e-mail/permalink metadata; none applies
                    warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
                    created = minari.create_dataset_from_buffers(
                        dataset_id=dataset_id,
                        buffer=buffers,
                        env=env,
                        algorithm_name=algorithm_name,
                        author=author,
                        description=description,
                    )
                    del created  # its storage points into the temp folder
                scratch.joinpath(*dataset_id.split("/"), "data").rename(build / "data")
                shutil.rmtree(scratch)
    finally:
        env.close()
    return minari.MinariDataset(MinariStorage.read(final / "data"))


@contextmanager
def _data_path_restored() -> Iterator[None]:
    """Put ``MINARI_DATASETS_PATH`` back as it was (set, or not) when the block ends."""
    previous = os.environ.get(_PATH_VARIABLE)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(_PATH_VARIABLE, None)
        else:
            os.environ[_PATH_VARIABLE] = previous


def minari_load_command(dataset_id: str, root: str | os.PathLike[str] | None = None) -> str:
    """A shell line that loads the dataset ``dataset_id`` stored under ``root`` (default: Minari's data path).

    >>> print(minari_load_command("steer/walk-v0", "/data/minari"))
    MINARI_DATASETS_PATH=/data/minari python -c "import minari; print(minari.load_dataset('steer/walk-v0'))"
    """
    dataset_id = check_minari_id(dataset_id)
    code = f"import minari; print(minari.load_dataset({dataset_id!r}))"
    line = f'python -c "{code}"'
    if root is None:
        return line
    return f"{_PATH_VARIABLE}={shlex.quote(os.path.abspath(os.path.expanduser(os.fspath(root))))} {line}"
