# What the train_*_checkpoint recipes share; they source it: strict mode, the repository root as the
# working folder, the Python to run ($PY: $PYTHON, else the venv's) and their arguments.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-.venv/bin/python}

# recipe_args DEFAULT_DATA_DIR "$@": CHECK=1 when the first argument is --check, DATA_DIR the next
# argument (default DEFAULT_DATA_DIR).
recipe_args() {
  local default=$1
  shift
  CHECK=0
  if [ "${1:-}" = "--check" ]; then CHECK=1; shift; fi
  DATA_DIR=${1:-$default}
}

# check_dp DATA RECORD: with --check, re-run the first 200 DP training steps on DATA and compare the loss
# curve with the shipped RECORD (exit 1 if it differs); the recipe ends there.
check_dp() {
  if [ "$CHECK" = 1 ]; then
    exec "$PY" -m steer_envs.baselines.training --policy dp --dataset "$1" --check "$2" --check-steps 200
  fi
}
