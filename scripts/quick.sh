#!/usr/bin/env bash
# The main job: a few-minute benchmark tour over the registered envs, from a fresh clone.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/bootstrap.sh
export MUJOCO_GL=${MUJOCO_GL:-osmesa}
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-$MUJOCO_GL}
exec .venv/bin/steer-bench run quick --out "${OUT:-runs/quick}" "$@"
