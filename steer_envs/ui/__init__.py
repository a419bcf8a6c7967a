"""steer-ui: steer a frozen policy by hand in the browser, or through :class:`Session` in Python.

``Session`` needs only the core dependencies; the web server (``steer-ui``,
:mod:`steer_envs.ui.server`) needs the ``ui`` extra (FastAPI, uvicorn).
"""

from steer_envs.ui.session import Session, SteerOutcome, SteerSettings, StepOutcome
from steer_envs.ui.views import PixelMap, SessionError

__all__ = ["PixelMap", "Session", "SessionError", "SteerOutcome", "SteerSettings", "StepOutcome"]
