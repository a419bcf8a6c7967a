#!/usr/bin/env bash
# Run the default test suite (everything not marked slow), from a fresh clone.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/bootstrap.sh
export MUJOCO_GL=${MUJOCO_GL:-osmesa}
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-$MUJOCO_GL}
exec .venv/bin/python -m pytest -n auto "$@"
