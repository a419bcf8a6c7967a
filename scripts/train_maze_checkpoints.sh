#!/usr/bin/env bash
# Reproduce the shipped Maze2D-Large checkpoints (baselines/checkpoints/maze2d_large/{dp,act}.*).
#
# 1. the D4RL-style random walk: 1M raw steps (x4 subsampled -> 250k samples), seed 0;
# 2. the Diffusion Policy (preset `cpu`: 1.7M parameters, 40k steps at batch 256, compiled), resumable:
#    ~3.5 h of one core; stop it any time and run this script again to continue from DATA_DIR/dp-run.
#    The shipped dp.safetensors began on a GPU (its record: `command`, `first_device`, `moved_at`): the
#    first 21,618 steps ran on an H200, the rest on a CPU (`--resume DIR --device cpu`). A run of this
#    recipe on a CPU alone draws other diffusion noise, so it ends with other weights: run end to end on
#    once (6.5 h of one core beside other jobs, resumed 3 times; final loss 0.0414 vs 0.0417) it
#    scores as the shipped DP does (RS collision 0.030 vs 0.036, all four Table 2.1 findings; see
#    docs/results.md).
# 3. ACT with a fixed seed and ONE torch thread: bit-identical for the same thread count, torch
#    version and CPU kind (oneDNN's reductions depend on the thread count). It can run beside step 2.
#    Both use the policy's `cpu` preset (baselines/{diffusion,act}/configuration.py).
#
# Usage: scripts/train_maze_checkpoints.sh [--check] [DATA_DIR]   (default: runs/maze2d-data)
#   --check  regenerate the data, then re-run only the first steps of both recorded runs
#            (200 DP steps, 100 ACT steps; ~5 minutes) and compare their loss curves with the
#            shipped records; exit 1 if either differs (the DP's began on a GPU: its CPU replay
#            draws other noise and is held to 10 %, ACT's to 1e-3).
source "$(dirname "$0")/recipe.sh"
recipe_args runs/maze2d-data "$@"
DATA="$DATA_DIR/maze2d-large-randomwalk-seed0.npz"
OUT=baselines/checkpoints/maze2d_large

"$PY" -m steer_envs.data.maze_random_walk --maze large --steps 1000000 --seed 0 --out "$DATA"
if [ "$CHECK" = 1 ]; then
  "$PY" -m steer_envs.baselines.training --policy dp --dataset "$DATA" --check "$OUT/dp.json" --check-steps 200
  "$PY" -m steer_envs.baselines.training --policy act --dataset "$DATA" --check "$OUT/act.json" --check-steps 100
  exit 0
fi
RUN="$DATA_DIR/dp-run"
if [ -e "$RUN/run.json" ]; then
  "$PY" -m steer_envs.baselines.training --resume "$RUN" --out "$PWD/$OUT/dp.safetensors"
else
  "$PY" -m steer_envs.baselines.training --policy dp --preset cpu --dataset "$DATA" --run-dir "$RUN" \
      --out "$PWD/$OUT/dp.safetensors" --compile --seed 0 --threads 1
fi
"$PY" -m steer_envs.baselines.training --policy act --preset cpu --dataset "$DATA" --out "$OUT/act.safetensors" \
    --steps 3000 --seed 0 --threads 1
