#!/usr/bin/env bash
# Regenerate requirements/constraints.txt: one resolver pass over all extras in a
# scratch venv, then freeze. Review the diff before committing.
set -euo pipefail
cd "$(dirname "$0")/.."
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"${PYTHON:-python3.11}" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --upgrade pip
# torch is pinned to the CPU build; robosuite forces numpy<2 and mujoco<3.4
"$tmp/venv/bin/python" -m pip install -q "torch==2.13.0" ".[all,dev,docs]"
{
  echo "# Known-good pins for Python 3.11 (one resolver pass of .[all,dev,docs]: the full dev environment)."
  echo "# numpy<2 and mujoco<3.4 are forced by robosuite 1.5.2 (mink needs numpy<2; mujoco 4 breaks robosuite);"
  echo "# the bare install (no extras) allows numpy 2: tests/test_packaging.py checks it."
  echo "# Regenerate: scripts/lock.sh"
  "$tmp/venv/bin/python" -m pip freeze --exclude-editable | grep -v '^steer-envs' | sed 's/^torch==\(.*\)+cpu$/torch==\1/'
} > requirements/constraints.txt.tmp
mv requirements/constraints.txt.tmp requirements/constraints.txt
echo "wrote requirements/constraints.txt"
