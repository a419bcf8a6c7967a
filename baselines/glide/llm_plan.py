"""LLM plans for GLiDE: prompt, provider interface and response parsing (thesis §4.2, appendix).

GLiDE asks an LLM for (a) a step-by-step plan, whose steps are the modes,
(b) which steps can directly follow which (the feasibility of transitions),
(c) a subset of the available state features and (d) a goal feature per step
(the pseudo-attractor of GLiDE+BC). The response format is the thesis
appendix's: Python literals inside ``<plan>``, ``<feasibility>``,
``<selected_features>`` and ``<goal>`` (also ``<goals>``, as in the recorded
Square response) tags, e.g.::

    <plan>
    steps = [{'id': 1, 'desc': 'Reach the can'}, {'id': 2, 'desc': 'Grasp the can'}]
    </plan>
    <feasibility>
    feasibility = {(1, 2): True}   # comments are allowed
    </feasibility>

:func:`parse_plan_response` turns that into a :class:`GlidePlan`, whose
:meth:`GlidePlan.task_spec` is a :class:`~steer_envs.core.task.TaskSpec`; the
feasibility matrix ``F`` of §4.2 is ``task_spec().feasibility_matrix()``
(negative shortest path between modes). Any LLM client plugs in through the
:class:`LLMProvider` protocol (one method, ``complete(prompt) -> str``);
:class:`RecordedProvider` replays stored responses (no network) for tests.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from steer_envs.core.task import TaskSpec

#: the longest LLM response :func:`parse_plan_response` reads (a plan is a few kB)
MAX_RESPONSE_CHARS = 1_000_000

#: the thesis appendix's instructions (the "clean the plate" example), sent before the task.
SYSTEM_PROMPT = """You are an expert in generating robot action plans and features.

Given a language description of a task, such as "clean the plate in a sink," you should first generate an abstract \
plan for the task. Put them in <plan></plan>. The plan is a list of steps. You should ignore object finding or \
localization actions. For example,
<plan>
steps = [{'id': 1, 'desc': 'Reach the plate'},
 {'id': 2, 'desc': 'Close gripper to grasp the plate'},
 {'id': 3, 'desc': 'Move to the sink'},
 {'id': 4, 'desc': 'Turn on the faucet'}]
</plan>

Next, you should generate a feasibility matrix between all the steps. Put them in <feasibility></feasibility>
<feasibility>
feasibility = {
  (1, 2): True,   # after reaching the plate, we can directly close the gripper
  (1, 3): False,  # after reaching the plate, we can't directly move to the sink
  (1, 4): False,  # after reaching the plate, we can't directly turn on the faucet
  (2, 3): True,   # after closing the gripper, we can directly move to the sink
  (2, 4): False,  # after closing the gripper, we can't directly turn on the faucet
  (3, 4): True,   # after moving to the sink, we can directly turn on the faucet
}
</feasibility>

The user will also give you a list of available features, such as robot poses, object poses. An example is the \
following:
<available_features>
available_features = ['plate_pos', 'plate_quat', 'plate_to_robot0_eef_pos', 'plate_to_robot0_eef_quat', 'sink_pos', \
'sink_quat', 'sink_to_robot0_eef_pos', 'sink_to_robot0_eef_quat', 'faucet_pos', 'faucet_quat', \
'faucet_to_robot0_eef_pos', 'faucet_to_robot0_eef_quat', 'robot0_eef_pos', 'robot0_eef_quat', 'gripper_state']
</available_features>
We will use the following convention: XXX_pos and XXX_quat denote the pose of the object. XXX_to_robot_eef denotes \
the relative pose between the object and the robot end-effector.

You should select a subset of features. Such as:
<selected_features>
features = ['plate_to_robot0_eef_pos', 'plate_to_robot0_eef_quat', 'sink_to_robot0_eef_pos', \
'sink_to_robot0_eef_quat', 'faucet_to_robot0_eef_pos', 'faucet_to_robot0_eef_quat', 'gripper_state']
</selected_features>

For each step, you also need to generate a "goal" pose, which is either an absolute pose of the robot or a relative \
pose between the robot and another object. In this case,
<goal>
goals = [
  {'id': '1', 'feature': 'plate_to_robot0_eef_pos'},
  {'id': '2', 'feature': 'plate_to_robot0_eef_pos'},
  {'id': '3', 'feature': 'sink_to_robot0_eef_pos'},
  {'id': '4', 'feature': 'faucet_to_robot0_eef_pos'},
]
</goal>
"""


@runtime_checkable
class LLMProvider(Protocol):
    """Anything that completes a prompt: wrap your LLM client in one method."""

    def complete(self, prompt: str) -> str:
        """The model's text response to ``prompt``."""
        ...


class RecordedProvider:
    """Replays recorded responses: ``responses`` maps a key found in the prompt to a response.

    The first key that occurs in the prompt (in insertion order) wins, so keys
    can be task descriptions. No network; used by the tests and examples.

    >>> provider = RecordedProvider({"lift": "<plan>steps = []</plan>"})
    >>> provider.complete("Task: lift the cube"), len(provider.prompts)
    ('<plan>steps = []</plan>', 1)
    """

    def __init__(self, responses: Mapping[str, str]) -> None:
        if not isinstance(responses, Mapping) or not responses:
            raise ValueError("responses must be a non-empty mapping prompt key -> response text")
        for key, text in responses.items():
            if not isinstance(key, str) or not isinstance(text, str):
                raise TypeError("responses must map str keys to str responses")
        self.responses = dict(responses)
        self.prompts: list[str] = []

    @classmethod
    def from_files(cls, files: Mapping[str, str | Path]) -> RecordedProvider:
        """Responses read from text files: key -> path."""
        return cls({key: Path(p).read_text(encoding="utf-8") for key, p in files.items()})

    def complete(self, prompt: str) -> str:
        if not isinstance(prompt, str):
            raise TypeError(f"prompt must be a str, got {type(prompt).__name__}")
        self.prompts.append(prompt)
        for key, text in self.responses.items():
            if key in prompt:
                return text
        raise KeyError(f"no recorded response matches the prompt (keys: {sorted(self.responses)})")


def build_prompt(task: str, available_features: Sequence[str]) -> str:
    """The full prompt: thesis instructions + task description + available features.

    >>> prompt = build_prompt("Lift the cube.", ["cube_pos", "gripper_state"])
    >>> prompt.startswith(SYSTEM_PROMPT), "available_features = ['cube_pos', 'gripper_state']" in prompt
    (True, True)
    """
    if not isinstance(task, str):
        raise TypeError(f"task must be a str, got {type(task).__name__}")
    if not task.strip():
        raise ValueError("task must be a non-empty description")
    if isinstance(available_features, (str, bytes)):
        raise TypeError("available_features must be a sequence of feature names, not one string")
    feats = list(available_features)
    if not all(isinstance(f, str) and f for f in feats):
        raise TypeError("available_features must be non-empty strings")
    return (
        f"{SYSTEM_PROMPT}\nTask: {task.strip()} Available features:\n"
        f"<available_features>\navailable_features = {feats!r}\n</available_features>\n"
    )


# ----------------------------------------------------------------------------- parsing
@dataclass(frozen=True)
class PlanStep:
    """One step (mode) of the plan."""

    id: int
    desc: str


@dataclass(frozen=True)
class GlidePlan:
    """A parsed LLM response.

    Attributes:
        steps: the plan, in order; step ``i`` is mode ``i`` of the classifier.
        feasibility: ``(i, j) -> bool`` as the LLM answered (step ids).
        features: the selected state features (empty if the tag is missing).
        goals: step id -> goal feature (empty if the tag is missing).
    """

    steps: tuple[PlanStep, ...]
    feasibility: Mapping[tuple[int, int], bool]
    features: tuple[str, ...] = ()
    goals: Mapping[int, str] | None = None

    @property
    def num_modes(self) -> int:
        return len(self.steps)

    def mode_names(self) -> tuple[str, ...]:
        """Mode names ``"<id>: <desc>"`` (unique even when descriptions repeat)."""
        return tuple(f"{s.id}: {s.desc}" for s in self.steps)

    def task_spec(self, name: str = "llm-plan", *, symmetric: bool = True) -> TaskSpec:
        """The plan as a :class:`TaskSpec` (first step initial, last step goal).

        The LLM is asked whether two steps are *directly connected*; with
        ``symmetric`` (default) a ``True`` pair connects both ways, so moving
        back a step is free and only skipping ahead costs, as in the thesis's
        sequential tasks. With ``symmetric=False`` only the listed direction is
        allowed.
        """
        names = self.mode_names()
        index = {s.id: i for i, s in enumerate(self.steps)}
        transitions = set()
        for (a, b), ok in self.feasibility.items():
            if ok:
                transitions.add((names[index[a]], names[index[b]]))
                if symmetric:
                    transitions.add((names[index[b]], names[index[a]]))
        return TaskSpec(name=name, modes=names, transitions=frozenset(transitions))

    def feasibility_matrix(
        self, convention: Literal["shortest_path", "forward"] = "shortest_path", *, symmetric: bool = True
    ) -> np.ndarray:
        """GLiDE's ``F`` (thesis §4.2): ``-(shortest path - 1)`` between steps, 0 for direct moves."""
        return self.task_spec(symmetric=symmetric).feasibility_matrix(convention)


_TAGS = {
    "plan": ("plan",),
    "feasibility": ("feasibility",),
    "selected_features": ("selected_features",),
    "goal": ("goal", "goals"),
}


def extract_tag(text: str, tag: str) -> str | None:
    """Content of the first ``<tag>...</tag>`` in ``text`` (None if absent).

    >>> extract_tag("a <plan>x = 1</plan> b", "plan"), extract_tag("no tags", "plan")
    ('x = 1', None)
    """
    m = re.search(rf"<{re.escape(tag)}>(.*?)</{re.escape(tag)}>", text, flags=re.DOTALL)
    return None if m is None else m.group(1)


def _literal(body: str, tag: str) -> Any:
    """Evaluate ``name = <python literal>`` (or a bare literal) safely with ``ast.literal_eval``."""
    code = body.strip()
    m = re.match(r"^[A-Za-z_]\w*\s*=\s*", code)
    if m:
        code = code[m.end() :]
    try:
        return ast.literal_eval(code)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as err:
        raise ValueError(f"<{tag}> does not hold a Python literal: {type(err).__name__}: {err}") from None


def _as_int(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise ValueError(f"{what} must be an integer id, got {value!r}")
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, str) and value.strip().lstrip("-").isdigit():
        return int(value.strip())
    raise ValueError(f"{what} must be an integer id, got {value!r}")


def _plan_steps(body: str) -> list[PlanStep]:
    """The steps of a ``<plan>`` body: at least two, with distinct integer ids."""
    raw_steps = _literal(body, "plan")
    if not isinstance(raw_steps, (list, tuple)) or not raw_steps:
        raise ValueError("<plan> must be a non-empty list of {'id': ..., 'desc': ...} dicts")
    steps = []
    for s in raw_steps:
        if not isinstance(s, Mapping) or "id" not in s or "desc" not in s:
            raise ValueError(f"<plan> step {s!r} must be a dict with 'id' and 'desc'")
        steps.append(PlanStep(_as_int(s["id"], "<plan> step id"), str(s["desc"]).strip()))
    ids = [s.id for s in steps]
    if len(set(ids)) != len(ids):
        raise ValueError(f"<plan> has duplicate step ids: {ids}")
    if len(steps) < 2:
        raise ValueError("<plan> must have at least two steps (modes)")
    return steps


def _plan_feasibility(body: str, ids: list[int]) -> dict[tuple[int, int], bool]:
    """The ``<feasibility>`` body's ``{(i, j): bool}`` over the plan's step ``ids``."""
    raw_feas = _literal(body, "feasibility")
    if not isinstance(raw_feas, Mapping):
        raise ValueError("<feasibility> must be a dict {(i, j): bool}")
    feas: dict[tuple[int, int], bool] = {}
    for pair, ok in raw_feas.items():
        if not (isinstance(pair, tuple) and len(pair) == 2):
            raise ValueError(f"<feasibility> key {pair!r} must be a pair of step ids")
        a, b = _as_int(pair[0], "<feasibility> step id"), _as_int(pair[1], "<feasibility> step id")
        if a not in ids or b not in ids:
            raise ValueError(f"<feasibility> pair ({a}, {b}) names a step not in the plan {ids}")
        if not isinstance(ok, (bool, np.bool_)):
            raise ValueError(f"<feasibility> value of ({a}, {b}) must be True/False, got {ok!r}")
        feas[(a, b)] = bool(ok)
    return feas


def _plan_goals(body: str, ids: list[int]) -> dict[int, str]:
    """The ``<goal>`` body's goal feature of each step (by id) that has one."""
    raw = _literal(body, "goal")
    if not isinstance(raw, (list, tuple)):
        raise ValueError("<goal> must be a list of {'id': ..., 'feature': ...} dicts")
    goals: dict[int, str] = {}
    for g in raw:
        if not isinstance(g, Mapping) or "id" not in g or "feature" not in g:
            raise ValueError(f"<goal> entry {g!r} must be a dict with 'id' and 'feature'")
        gid = _as_int(g["id"], "<goal> step id")
        if gid not in ids:
            raise ValueError(f"<goal> names step {gid}, which is not in the plan {ids}")
        goals[gid] = str(g["feature"]).strip()
    return goals


def parse_plan_response(text: str) -> GlidePlan:
    """Parse an LLM response in the thesis appendix format into a :class:`GlidePlan`.

    ``<plan>`` and ``<feasibility>`` are required; ``<selected_features>`` and
    ``<goal>``/``<goals>`` are optional. Raises ValueError naming the tag on
    malformed content, unknown step ids or duplicate ids.

    >>> plan = parse_plan_response(
    ...     "<plan>steps = [{'id': 1, 'desc': 'Reach'}, {'id': 2, 'desc': 'Grasp'}, {'id': 3, 'desc': 'Lift'}]</plan>"
    ...     "<feasibility>feasibility = {(1, 2): True, (2, 3): True, (1, 3): False}</feasibility>"
    ... )
    >>> plan.mode_names()
    ('1: Reach', '2: Grasp', '3: Lift')
    >>> plan.feasibility_matrix().tolist()  # skipping a step costs one infeasible move
    [[0.0, 0.0, -1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__}")
    if len(text) > MAX_RESPONSE_CHARS:
        raise ValueError(f"response has {len(text)} characters, more than the {MAX_RESPONSE_CHARS} accepted")
    bodies: dict[str, str | None] = {}
    for key, names in _TAGS.items():
        bodies[key] = next((b for b in (extract_tag(text, n) for n in names) if b is not None), None)
    if bodies["plan"] is None:
        raise ValueError("response has no <plan>...</plan>")
    if bodies["feasibility"] is None:
        raise ValueError("response has no <feasibility>...</feasibility>")

    steps = _plan_steps(bodies["plan"])
    ids = [s.id for s in steps]
    feas = _plan_feasibility(bodies["feasibility"], ids)
    features: tuple[str, ...] = ()
    if bodies["selected_features"] is not None:
        raw = _literal(bodies["selected_features"], "selected_features")
        if not isinstance(raw, (list, tuple)) or not all(isinstance(f, str) for f in raw):
            raise ValueError("<selected_features> must be a list of feature names")
        features = tuple(f.strip() for f in raw)
    goals = {} if bodies["goal"] is None else _plan_goals(bodies["goal"], ids)
    return GlidePlan(steps=tuple(steps), feasibility=feas, features=features, goals=goals)


def request_plan(provider: LLMProvider, task: str, available_features: Iterable[str]) -> GlidePlan:
    """Prompt ``provider`` for a plan of ``task`` and parse its response.

    >>> reply = "<plan>[{'id': 1, 'desc': 'a'}, {'id': 2, 'desc': 'b'}]</plan><feasibility>{(1, 2): True}</feasibility>"
    >>> request_plan(RecordedProvider({"Push": reply}), "Push the block.", ["block_pos"]).num_modes
    2
    """
    if not isinstance(provider, LLMProvider):
        raise TypeError(f"provider must implement complete(prompt) -> str, got {type(provider).__name__}")
    response = provider.complete(build_prompt(task, list(available_features)))
    if not isinstance(response, str):
        raise TypeError(f"provider.complete must return a str, got {type(response).__name__}")
    return parse_plan_response(response)


__all__ = [
    "MAX_RESPONSE_CHARS",
    "SYSTEM_PROMPT",
    "GlidePlan",
    "LLMProvider",
    "PlanStep",
    "RecordedProvider",
    "build_prompt",
    "extract_tag",
    "parse_plan_response",
    "request_plan",
]
