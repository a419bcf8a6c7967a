#!/usr/bin/env bash
# Reproduce the shipped Maze2D-Large checkpoints (baselines/checkpoints/maze2d_large/{dp,act}.*).
#
# 1. the D4RL-style random walk: 1M raw steps (x4 subsampled -> 250k samples), seed 0;
# 2. the Diffusion Policy, then ACT, on it, each with a fixed seed and ONE torch thread: the
#    checkpoints are bit-identical for the same thread count, torch version and CPU kind
#    (oneDNN's reductions depend on the thread count). Both commands can run side by side.
#    Each uses the policy's `cpu` preset (baselines/{diffusion,act}/configuration.py).
#
# Usage: scripts/train_maze_checkpoints.sh [--check] [DATA_DIR]   (default: runs/maze2d-data)
#   --check  regenerate the data, then re-run only the first steps of both recorded runs
#            (200 DP steps, 100 ACT steps; a few minutes) and compare their loss curves
#            with the shipped records; exit 1 if either differs.
set -euo pipefail
cd "$(dirname "$0")/.."
CHECK=0
if [ "${1:-}" = "--check" ]; then CHECK=1; shift; fi
PY=${PYTHON:-.venv/bin/python}
DATA_DIR=${1:-runs/maze2d-data}
DATA="$DATA_DIR/maze2d-large-randomwalk-seed0.npz"
OUT=baselines/checkpoints/maze2d_large

"$PY" -m steer_envs.data.maze_random_walk --maze large --steps 1000000 --seed 0 --out "$DATA"
if [ "$CHECK" = 1 ]; then
  "$PY" -m steer_envs.baselines.training --policy dp --dataset "$DATA" --check "$OUT/dp.json" --check-steps 200
  "$PY" -m steer_envs.baselines.training --policy act --dataset "$DATA" --check "$OUT/act.json" --check-steps 100
  exit 0
fi
"$PY" -m steer_envs.baselines.training --policy dp --preset cpu --dataset "$DATA" --out "$OUT/dp.safetensors" \
    --steps 30000 --seed 0 --threads 1
"$PY" -m steer_envs.baselines.training --policy act --preset cpu --dataset "$DATA" --out "$OUT/act.safetensors" \
    --steps 3000 --seed 0 --threads 1
