#!/usr/bin/env bash
# The interop tests: steer-envs against the real LeRobot (policy adapter, LeRobotDataset), robomimic and
# Minari. LeRobot's pins (torch<2.11, diffusers<0.36, ...) clash with the main environment's, so these run
# in a separate venv, .venv-interop, built once and reused while requirements/interop.txt and setup.cfg are
# unchanged (a stamp holds their hash). About 6 GB: LeRobot's torch is a CUDA build.
#   scripts/test_interop.sh            build if needed, then run tests/interop
#   scripts/test_interop.sh --lock     re-resolve INTEROP_PACKAGES and rewrite requirements/interop.txt
# Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null 2>&1 || PYTHON=python3
INTEROP_PACKAGES=("lerobot==0.4.4" "robomimic==0.3.0" "minari[hdf5]>=0.5" "pytest>=8")
venv=.venv-interop

if [ "${1:-}" = --lock ]; then
  shift
  tmp=$(mktemp -d)
  "$PYTHON" -m venv "$tmp/venv"
  "$tmp/venv/bin/python" -m pip install -q --dry-run --ignore-installed --report "$tmp/report.json" \
    "${INTEROP_PACKAGES[@]}" -e .
  {
    sed -n '1,/^# Regenerate/p' requirements/interop.txt
    "$tmp/venv/bin/python" - "$tmp/report.json" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
pins = sorted(f"{p['metadata']['name']}=={p['metadata']['version']}" for p in report["install"]
              if p["metadata"]["name"] != "steer-envs")
print("\n".join(pins))
PY
  } > "$tmp/interop.txt"
  mv "$tmp/interop.txt" requirements/interop.txt
  rm -rf "$tmp"
  echo "[interop] wrote requirements/interop.txt"
fi

if [ ! -x $venv/bin/python ]; then
  echo "[interop] creating $venv with $PYTHON"
  "$PYTHON" -m venv $venv
fi
stamp=$venv/.steer-envs-stamp
want=$(cat setup.cfg pyproject.toml requirements/interop.txt | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "[interop] installing LeRobot, robomimic, Minari and steer-envs (a few minutes the first time)"
  log=$venv/install.log
  if ! { $venv/bin/python -m pip install -q --upgrade "pip>=24" \
         && $venv/bin/python -m pip install -q -r requirements/interop.txt -e .; } >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "[interop] pip install failed; full log in $log" >&2
    exit 1
  fi
  echo "$want" > "$stamp"
fi
export MUJOCO_GL=${MUJOCO_GL:-osmesa}
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-$MUJOCO_GL}
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
export STEER_INTEROP=1 HF_DATASETS_DISABLE_PROGRESS_BARS=1 HF_HUB_OFFLINE=1
exec $venv/bin/python -m pytest -p no:cacheprovider -o addopts="-ra --strict-markers" -s tests/interop "$@"
