"""Test-wide settings: headless MuJoCo rendering unless the user chose a backend; tests/interop only on request.

tests/interop needs LeRobot and robomimic, whose pins clash with this
environment's: ``scripts/test_interop.sh`` runs it in its own venv
(``STEER_INTEROP=1``).
"""

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

#: folders pytest does not collect here (tests/interop runs in scripts/test_interop.sh)
collect_ignore = [] if os.environ.get("STEER_INTEROP") == "1" else ["interop"]
