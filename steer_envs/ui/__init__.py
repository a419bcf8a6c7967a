"""steer-ui: steer a frozen policy (or push a controller) by hand in the browser, or in Python.

:class:`Session` steers a policy's plans (ITPS), :class:`PushSession` pushes a
closed-loop controller (TLI, GLiDE); :data:`DOMAINS` declares what each domain offers.

``Session`` needs only the core dependencies; the web server (``steer-ui``,
:mod:`steer_envs.ui.server`) needs the ``ui`` extra (FastAPI, uvicorn).
"""

from steer_envs.ui.domains import DOMAINS, Domain
from steer_envs.ui.push_session import PushSession
from steer_envs.ui.session import Session, SteerOutcome, SteerSettings, StepOutcome
from steer_envs.ui.views import PixelMap, SessionError

__all__ = [
    "DOMAINS",
    "Domain",
    "PixelMap",
    "PushSession",
    "Session",
    "SessionError",
    "SteerOutcome",
    "SteerSettings",
    "StepOutcome",
]
