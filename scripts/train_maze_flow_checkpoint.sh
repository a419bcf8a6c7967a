#!/usr/bin/env bash
# Reproduce the Maze2D-Large flow-matching policy (baselines/checkpoints/maze2d_large/flow.*) that
# itps-flow-safety compares with the shipped DP: DP's `cpu` recipe (same network, 40k steps at batch 256, compiled) as a
# rectified flow, on the same random walk (1M raw steps, seed 0; regenerated bit for bit when missing).
# Resumable: ~5 h of one core; stop it any time and run this script again to continue from DATA_DIR/flow-run.
#
#   scripts/train_maze_flow_checkpoint.sh [--check] [DATA_DIR]    (default runs/maze2d-data)
#   --check  re-run only the first 200 training steps and compare the loss curve with the shipped record
source "$(dirname "$0")/recipe.sh"
recipe_args runs/maze2d-data "$@"
DATA="$DATA_DIR/maze2d-large-randomwalk-seed0.npz"
OUT=baselines/checkpoints/maze2d_large
RUN="$DATA_DIR/flow-run"

[ -e "$DATA" ] || "$PY" -m steer_envs.data.maze_random_walk --maze large --steps 1000000 --seed 0 --out "$DATA"
if [ "$CHECK" = 1 ]; then
  exec "$PY" -m steer_envs.baselines.training --policy flow --dataset "$DATA" --check "$OUT/flow.json" \
      --check-steps 200
fi
if [ -e "$RUN/run.json" ]; then
  "$PY" -m steer_envs.baselines.training --resume "$RUN" --out "$PWD/$OUT/flow.safetensors"
else
  "$PY" -m steer_envs.baselines.training --policy flow --preset cpu --dataset "$DATA" --run-dir "$RUN" \
      --out "$PWD/$OUT/flow.safetensors" --compile --seed 0 --threads 1
fi
