"""Recording a wrapper's constructor arguments for ``env.spec``, read off the constructor's own parameters.

Gymnasium shows a wrapper stack in ``env.spec.additional_wrappers`` from the
keyword arguments each wrapper passes to ``RecordConstructorArgs.__init__``.
:func:`record_constructor_args` passes every parameter of the constructor but
``self`` and ``env`` (the caller's ``locals()`` at the top of ``__init__``),
so a new parameter is recorded without a new line and none is left out.

>>> import gymnasium as gym
>>> class Scaled(gym.ActionWrapper, gym.utils.RecordConstructorArgs):
...     def __init__(self, env, scale=1.0, *, clip=None):
...         record_constructor_args(self, locals())
...         gym.ActionWrapper.__init__(self, env)
>>> Scaled(gym.make("CartPole-v1"), 2.0)._saved_kwargs
{'scale': 2.0, 'clip': None}
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

__all__ = ["record_constructor_args"]

#: the names of ``locals()`` that are not recorded: the wrapper, the wrapped env, a ``super()`` cell
NOT_RECORDED = frozenset({"self", "env", "__class__"})


def record_constructor_args(
    wrapper: gym.utils.RecordConstructorArgs, arguments: Mapping[str, Any], *, deepcopy: bool = True, **changes: Any
) -> None:
    """``RecordConstructorArgs.__init__`` with ``arguments`` (but ``self`` and ``env``), then ``changes``.

    Call it first in ``__init__`` with ``locals()``, before anything else is
    bound. ``deepcopy=False`` records the values themselves (e.g. a bound
    method whose owner must not be copied); ``changes`` replace recorded values
    (e.g. a copy made by the caller).
    """
    kwargs = {name: value for name, value in arguments.items() if name not in NOT_RECORDED}
    gym.utils.RecordConstructorArgs.__init__(wrapper, _disable_deepcopy=not deepcopy, **{**kwargs, **changes})
