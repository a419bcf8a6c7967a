"""What steer-ui can open: one declaration per domain, sent to the page, which builds its controls from it.

A :class:`Domain` names its env, what drives the agent (a frozen policy a
person steers, ITPS; or a controller a person pushes, TLI and GLiDE), the
interactions it offers (:data:`INTERACTIONS`: ``sketch``, ``point`` and
``nudge`` steer a policy; ``push`` drags the agent and watches the controller
recover) and the overlays it draws (:class:`Overlay`). The server sends
:meth:`Domain.declaration` in its ``ready`` message; the page builds the input
buttons, the legend and the panels from it, so a new domain is a declaration
here (plus, for a new overlay kind, its drawing in ``static/app.js``), not a
new page.

>>> DOMAINS["maze2d"].interactions
('sketch', 'point', 'nudge')
>>> DOMAINS["soup-scoop"].declaration("soup-scoop")["steering"]
False
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from steer_envs.core.validation import one_of
from steer_envs.ui.settings import SteerSettings

__all__ = [
    "DEFAULT_ENV",
    "DOMAINS",
    "INTERACTIONS",
    "OVERLAY_KINDS",
    "SESSION_KINDS",
    "Domain",
    "Interaction",
    "Overlay",
    "domain_named",
]

#: the env steer-ui opens by default (the one the shipped checkpoints plan in)
DEFAULT_ENV = "steer_envs/Maze2D-Large-v0"
#: ``"steer"``: a frozen trajectory policy steered by sketches / points / nudges (ITPS);
#: ``"push"``: a closed-loop controller the person pushes (TLI's LTL-DS, GLiDE+Planning)
SESSION_KINDS: tuple[str, ...] = ("steer", "push")
#: how the page draws an overlay: ``plans`` (the steered batch), ``image`` (an RGBA picture over the frame),
#: ``arrows`` (``[u, v, du, dv]`` rows), ``lines`` (polylines of pixels), ``markers`` (``[u, v]`` points),
#: ``strip`` (rows of mode indices along the run, drawn as coloured bars under the frame; the overlay's legend
#: gives mode ``k``'s name and colour in row ``k``)
OVERLAY_KINDS: tuple[str, ...] = ("plans", "image", "arrows", "lines", "markers", "strip")


@dataclass(frozen=True)
class Interaction:
    """One input mode of the page: its radio button, its hint, and the message a mouse gesture sends.

    ``gesture``: ``"path"`` (press, drag, release: the path), ``"click"`` (where the button is released)
    or ``"drag-agent"`` (from the agent to where it is released: the target).
    """

    kind: str
    label: str
    hint: str
    message: str
    gesture: str

    def as_dict(self, hint: str | None = None) -> dict[str, str]:
        """JSON-ready, with a domain's own ``hint`` if it has one."""
        return {
            "kind": self.kind,
            "label": self.label,
            "hint": hint or self.hint,
            "message": self.message,
            "gesture": self.gesture,
        }


#: every input mode a domain may offer
INTERACTIONS: dict[str, Interaction] = {
    "sketch": Interaction(
        "sketch", "Sketch", "Sketch mode: press and drag on the image to draw a path; the steered plans follow.",
        "steer", "path",
    ),
    "point": Interaction("point", "Point", "Point mode: click where the plans should go.", "steer", "click"),
    "nudge": Interaction(
        "nudge", "Nudge",
        "Nudge mode: drag from anywhere to where the agent should be pushed (a physical correction).",
        "nudge", "drag-agent",
    ),
    "push": Interaction(
        "push", "Push",
        "Push mode: drag the agent to where it should be pushed; the controller recovers from there.",
        "push", "drag-agent",
    ),
}  # fmt: skip


@dataclass(frozen=True)
class Overlay:
    """Something the page draws over the frame: ``name`` (its key in a frame's ``overlays``), how, and its legend.

    ``legend``: ``(label, CSS colour)`` rows of the legend (the ``plans`` kind adds its own rows).
    """

    name: str
    kind: str
    legend: tuple[tuple[str, str], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"name": self.name, "kind": self.kind, "legend": [list(row) for row in self.legend]}


#: the steered batch of an ITPS domain
PLANS = Overlay("plans", "plans")


@dataclass(frozen=True)
class Domain:
    """What steer-ui opens: an env, what drives it, the interactions it offers and the overlays it draws.

    Attributes:
        env_id / env_kwargs: the env (made with ``render_mode="rgb_array"``).
        policies: ``"steer"``: the policy kinds :func:`~steer_envs.ui.session.shared_policy` loads (the first
            is the default).
        settings: ``"steer"``: the default sampler and knobs.
        view: ``"pixels"`` (the env's affine ``pixel_to_xy``), ``"box"`` (a kinematic env's workspace box
            drawn top-down), ``"camera"`` (a robosuite camera with depth: a click lands on a surface) or
            ``"plane"`` (a robosuite camera; a drag moves the agent in the plane through it facing the camera).
        execute: ``"waypoints"`` (each plan waypoint is an env action), ``"skill"`` (a BlockStack pick /
            place skill), ``"kitchen-skill"`` (a Kitchen door / bowl skill) or ``"controller"`` (``"push"``).
        session: one of :data:`SESSION_KINDS`.
        title: what the page's header says.
        interactions: the input modes offered (:data:`INTERACTIONS`), the first selected at start.
        overlays: what the page draws over the frame.
        controller: ``"push"``: the name of :data:`~steer_envs.ui.drivers.CONTROLLERS` that drives the agent.
        steps: ``"push"``: env steps one Step (or play tick) runs.
        hints: per-interaction hints in this domain's words.
    """

    env_id: str
    env_kwargs: Mapping[str, Any]
    policies: tuple[str, ...] = ()
    settings: SteerSettings = field(default_factory=SteerSettings)
    view: str = "pixels"
    execute: str = "waypoints"
    session: str = "steer"
    title: str = ""
    interactions: tuple[str, ...] = ("sketch", "point", "nudge")
    overlays: tuple[Overlay, ...] = (PLANS,)
    controller: str = ""
    steps: int = 10
    hints: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        one_of(self.session, "session", SESSION_KINDS, owner="Domain")
        one_of(self.view, "view", ("pixels", "box", "camera", "plane"), owner="Domain")
        one_of(self.execute, "execute", ("waypoints", "skill", "kitchen-skill", "controller"), owner="Domain")
        for kind in self.interactions:
            one_of(kind, "interactions", tuple(INTERACTIONS), owner="Domain")
        for overlay in self.overlays:
            one_of(overlay.kind, "overlay kind", OVERLAY_KINDS, owner="Domain")
        if (self.session == "push") != (self.execute == "controller") or (self.session == "push") != bool(
            self.controller
        ):
            raise ValueError("Domain: a 'push' session runs a `controller` (execute='controller'); 'steer' does not")
        if self.session == "steer" and not self.policies:
            raise ValueError("Domain: a 'steer' session needs the policy kinds it can load")

    @property
    def steering(self) -> bool:
        """Whether a person steers a policy's plans here (sampler knobs shown) rather than pushing a controller."""
        return self.session == "steer"

    def declaration(self, name: str, kinds: tuple[str, ...] | None = None) -> dict[str, Any]:
        """What the page builds its controls from (``kinds``: the interactions the opened env really takes)."""
        offered = [k for k in self.interactions if kinds is None or k in kinds]
        return {
            "name": name,
            "title": self.title or name,
            "steering": self.steering,
            "interactions": [INTERACTIONS[k].as_dict(self.hints.get(k)) for k in offered],
            "overlays": [o.as_dict() for o in self.overlays],
        }


_MODE_MAP = Overlay("mode_map", "image", (("learned modes (tint)", "rgba(120, 120, 120, 0.5)"),))
_GLIDE_PATH = Overlay("plan", "lines", (("GLiDE+Planning's path", "#1b2a8f"),))
_FLOW = Overlay("flow", "arrows", (("LPV-DS flow of the current mode", "#149f9f"),))
_CUTS = Overlay("cuts", "lines", (("learned cuts (modulation)", "#c81ec8"),))
_ATTRACTOR = Overlay("attractor", "markers", (("the mode's attractor", "#f08c1e"),))
_TRAIL = Overlay("trail", "lines", (("the gripper's path", "#1b2a8f"),))
_TARGET = Overlay("target", "markers", (("the learned mode's attractor", "#f08c1e"),))
_LIFT_MODES = Overlay(
    "modes", "strip", (("mode reach", "#1b9e77"), ("mode lift", "#d95f02"), ("mode reach_height", "#7570b3"))
)
_ARM_FLOW = Overlay("flow", "arrows", (("LPV-DS flow of the current mode, (y, z) at the spoon's pitch", "#149f9f"),))

#: the domains steer-ui can open (``--domain``)
DOMAINS: dict[str, Domain] = {
    "maze2d": Domain(
        DEFAULT_ENV, {"sample_goal": False}, ("dp", "act"), SteerSettings(), title="Maze2D-Large (ITPS)",
        hints={"sketch": "Sketch mode: press and drag on the maze to draw a path; the steered plans follow."},
    ),
    # this DP runs 100 DDIM steps: GD with the clipped-output step at beta 25 aligns best (docs/results.md)
    "blockstack": Domain(
        "steer_envs/BlockStack-v0",
        {"fast_render": True, "render_size": 256},
        ("blockstack",),
        SteerSettings(sampler="GD", batch=16, guide_ratio=25.0, use_clipped_model_output=True),
        view="camera",
        execute="skill",
        title="BlockStack (ITPS)",
        interactions=("point", "sketch"),
        hints={"point": "Point mode: click a cube (or where a held cube should go); the skill plans follow."},
    ),
    # ITPS Table 2.3's DP-GD: beta 5 at every DDIM step
    "kitchen": Domain(
        "steer_envs/Kitchen-v0",
        {"task": "microwave", "fast_render": True},
        ("kitchen",),
        SteerSettings(sampler="GD", batch=16, guide_ratio=5.0),
        view="camera",
        execute="kitchen-skill",
        title="Kitchen (ITPS)",
        interactions=("point", "nudge"),
        hints={
            "point": "Point mode: click the door handle or the bowl (the click is lifted to 3D); skill plans follow.",
            "nudge": "Nudge mode: drag to a surface point to push the gripper there (a physical correction).",
        },
    ),
    "polygon-nav": Domain(
        "steer_envs/PolygonNav-3Mode-v0",
        {},
        view="box",
        execute="controller",
        session="push",
        title="PolygonNav-3Mode (GLiDE+Planning)",
        interactions=("push",),
        overlays=(_MODE_MAP, _GLIDE_PATH),
        controller="glide-planning",
        steps=5,
    ),
    "soup-scoop": Domain(
        "steer_envs/SoupScoop-v0",
        {},
        view="box",
        execute="controller",
        session="push",
        title="SoupScoop (TLI: LTL-DS)",
        interactions=("push",),
        overlays=(_FLOW, _CUTS, _ATTRACTOR),
        controller="ltl-ds",
        steps=20,
        hints={"push": "Push mode: drag the spoon to push it; a push that skips or undoes a mode makes LTL-DS replan."},
    ),
    # the front camera looks along -x: the spoon's (y, z) plane faces it
    "arm-scoop": Domain(
        "steer_envs/ArmScoop-v0",
        {"camera": "frontview", "render_size": 320, "fast_render": True},
        view="plane",
        execute="controller",
        session="push",
        title="ArmScoop (TLI: LTL-DS on the Panda arm)",
        interactions=("push",),
        overlays=(_ARM_FLOW, _CUTS, _ATTRACTOR),
        controller="ltl-ds",
        steps=20,
        hints={
            "push": "Push mode: drag the spoon (its pitch is kept): into the soup, out of it, past the target bowl; "
            "a push that skips or undoes a mode makes LTL-DS replan.",
        },
    ),
    "lift-glide": Domain(
        "steer_envs/Lift-v0",
        {"camera": "frontview", "render_size": 320, "fast_render": True},
        view="plane",
        execute="controller",
        session="push",
        title="Lift (GLiDE+BC over learned modes)",
        interactions=("push",),
        overlays=(_TRAIL, _TARGET, _LIFT_MODES),
        controller="glide-bc-arm",
        steps=10,
        hints={
            "push": "Push mode: drag the gripper (in the plane facing the camera); the strip under the image shows "
            "the learned mode beside the true one along the run.",
        },
    ),
}  # fmt: skip


def domain_named(name: str, owner: str = "steer-ui") -> Domain:
    """``DOMAINS[name]``, or a ``ValueError`` listing the names."""
    return DOMAINS[one_of(name, "domain", tuple(DOMAINS), owner=owner)]
