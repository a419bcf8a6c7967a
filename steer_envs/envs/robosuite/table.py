"""Pieces the custom robosuite scenes share: the table arena with the robot at its edge, object observables.

They run inside a robosuite env class's ``_load_model`` / ``_setup_observables``
(robosuite is imported when they are called, never by importing this module).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np


def table_arena(env: Any) -> Any:
    """Put robot 0 at the table's edge and return robosuite's ``TableArena`` of ``env``, its origin at 0."""
    from robosuite.models.arenas import TableArena

    xpos = env.robots[0].robot_model.base_xpos_offset["table"](env.table_full_size[0])
    env.robots[0].robot_model.set_base_xpos(xpos)
    arena = TableArena(
        table_full_size=env.table_full_size, table_friction=env.table_friction, table_offset=env.table_offset
    )
    arena.set_origin([0, 0, 0])
    return arena


def add_object_observables(
    env: Any, observables: Any, sensors: Iterable[tuple[str, Callable[[Any], np.ndarray]]]
) -> Any:
    """``observables`` with one ``object``-modality observable per ``(name, fn)`` at ``env``'s control rate."""
    from robosuite.utils.observables import Observable, sensor

    for name, fn in sensors:
        fn.__name__ = name
        observables[name] = Observable(name=name, sensor=sensor(modality="object")(fn), sampling_rate=env.control_freq)
    return observables
