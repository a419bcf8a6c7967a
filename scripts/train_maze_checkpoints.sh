#!/usr/bin/env bash
# Reproduce the shipped Maze2D-Large checkpoints (baselines/checkpoints/maze2d_large_{dp,act}.*).
#
# 1. the D4RL-style random walk: 1M raw steps (x4 subsampled -> 250k samples), seed 0;
# 2. the Diffusion Policy, then ACT, on it, each with a fixed seed and ONE torch thread: the
#    checkpoints are bit-identical for the same thread count, torch version and CPU kind
#    (oneDNN's reductions depend on the thread count). Both commands can run side by side.
#
# Usage: scripts/train_maze_checkpoints.sh [DATA_DIR]   (default: runs/maze2d-data)
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
DATA_DIR=${1:-runs/maze2d-data}
DATA="$DATA_DIR/maze2d-large-randomwalk-seed0.npz"
OUT=baselines/checkpoints

"$PY" -m steer_envs.data.maze_random_walk --maze large --steps 1000000 --seed 0 --out "$DATA"
"$PY" -m steer_envs.baselines.train_maze dp --data "$DATA" --out "$OUT/maze2d_large_dp.safetensors" \
    --steps 30000 --seed 0 --threads 1
"$PY" -m steer_envs.baselines.train_maze act --data "$DATA" --out "$OUT/maze2d_large_act.safetensors" \
    --steps 3000 --seed 0 --threads 1
