#!/usr/bin/env bash
# The default checks, from a fresh clone: ruff (lint + format), mypy, the documentation site's
# strict build, then the test suite (everything not marked slow). What CI runs (.ci/run calls this).
# Extra arguments go to pytest, e.g. `scripts/test.sh tests/envs -x`; STEER_SKIP_LINT=1 skips ruff, mypy
# and the docs build.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/bootstrap.sh
export MUJOCO_GL=${MUJOCO_GL:-osmesa}
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-$MUJOCO_GL}
if [ "${STEER_SKIP_LINT:-0}" != 1 ]; then
  echo "[test] ruff check"
  .venv/bin/ruff check .
  echo "[test] ruff format --check"
  .venv/bin/ruff format --check .
  echo "[test] mypy steer_envs wrappers baselines"
  .venv/bin/mypy steer_envs wrappers baselines
  echo "[test] mkdocs build --strict"
  # into a temp dir: the built site is not kept (site/ is git-ignored too); not --quiet, which
  # silences the very warnings --strict counts
  site_dir=$(mktemp -d)
  if ! NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict -d "$site_dir"; then
    rm -rf "$site_dir"
    exit 1
  fi
  rm -rf "$site_dir"
fi
exec .venv/bin/python -m pytest -n auto "$@"
