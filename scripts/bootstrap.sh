#!/usr/bin/env bash
# Set up everything steer-envs needs from a fresh clone: apt packages (when we
# may install them), a virtual environment in .venv and the pinned packages.
# Idempotent and quick when nothing changed (a stamp holds the hash of the inputs).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null 2>&1 || PYTHON=python3

# Offscreen MuJoCo rendering on CPUs needs OSMesa; steer-ui's browser test drives Debian's chromium.
APT_PACKAGES=(libosmesa6 chromium chromium-driver xvfb)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg"); done
if [ ${#missing[@]} -gt 0 ]; then
  sudo_cmd=()
  [ "$(id -u)" = 0 ] || sudo_cmd=(sudo)
  if [ "$(id -u)" = 0 ] || command -v sudo >/dev/null 2>&1; then
    echo "[bootstrap] apt-get install ${missing[*]}"
    ("${sudo_cmd[@]}" apt-get update -qq \
      && "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null) \
      || echo "[bootstrap] warning: could not install ${missing[*]}; MuJoCo rendering / the browser test may be unavailable" >&2
  else
    echo "[bootstrap] warning: ${missing[*]} missing and no root; MuJoCo rendering / the browser test may be unavailable" >&2
  fi
fi

if [ ! -x .venv/bin/python ]; then
  echo "[bootstrap] creating .venv with $PYTHON"
  "$PYTHON" -m venv .venv
fi

stamp=.venv/.steer-envs-stamp
want=$(cat setup.cfg pyproject.toml requirements/constraints.txt | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "[bootstrap] installing steer-envs and pinned dependencies (about 2 minutes the first time)"
  log=.venv/bootstrap.log
  # everything: every feature extra (all), the test tools (dev) and the docs site (docs), at the pinned versions.
  # torch==2.13.0 is pinned: a bare torch would pull a multi-GB CUDA build.
  if ! { .venv/bin/python -m pip install -q --upgrade "pip>=24" \
         && .venv/bin/python -m pip install -q -c requirements/constraints.txt -e ".[all,dev,docs]"; } >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "[bootstrap] pip install failed; full log in $log" >&2
    exit 1
  fi
  echo "$want" > "$stamp"
fi
