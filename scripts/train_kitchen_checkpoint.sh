#!/usr/bin/env bash
# Reproduce the shipped Kitchen skill policy (baselines/checkpoints/kitchen/dp.*).
#
# 1. the expert's skill data: 60 scenes, each recorded in both of the thesis's tasks, microwave
#    (open the door, pick the bowl, place it in the microwave, close the door) and sink (pick,
#    place in the sink), so that the scene cannot tell which task's first skill comes next, and
#    each episode once more with every skill starting after a push of the end effector toward
#    the skill's target (perturbed_starts: the states OP's correction leaves the arm in):
#    steer-bench suite itps-kitchen-data with every_task and perturbed_starts, one trial per
#    scene, resumable;
# 2. the plan data set: one (32 x [x, y, z, yaw, gripper]) plan per successful skill, the two
#    tasks and both kinds of start merged (python -m steer_envs.data.kitchen_shards
#    --every-task --perturbed-starts);
# 3. the Diffusion Policy, preset `kitchen` (baselines/diffusion/configuration.py), 20k steps,
#    seed 0, one torch thread (bit-identical for the same thread count, torch version and CPU kind;
#    --check replays the first steps on the thread count the record names).
#
# Usage: scripts/train_kitchen_checkpoint.sh [--check] [DATA_DIR]   (default: runs/kitchen-data)
#   --check  build (or reuse) the data, then re-run only the first 200 training steps and compare
#            the loss curve with the shipped record; exit 1 if it differs.
# WORKERS=N sets the data job's parallel workers (default 2).
source "$(dirname "$0")/recipe.sh"
recipe_args runs/kitchen-data "$@"
EPISODES=60
DATA="$DATA_DIR/kitchen-plans-${EPISODES}all-push.npz"
OUT=baselines/checkpoints/kitchen

export MUJOCO_GL=${MUJOCO_GL:-osmesa}
"$PY" -m steer_envs.bench run itps-kitchen-data --seeds "$EPISODES" --workers "${WORKERS:-2}" \
    --param "cache_dir=$DATA_DIR" --param every_task=true --param perturbed_starts=true --out "$DATA_DIR/run"
"$PY" -m steer_envs.data.kitchen_shards --cache-dir "$DATA_DIR" --episodes "$EPISODES" --every-task \
    --perturbed-starts --out "$DATA"
check_dp "$DATA" "$OUT/dp.json"
mkdir -p "$OUT"
"$PY" -m steer_envs.baselines.training --policy dp --preset kitchen --dataset "$DATA" \
    --steps 20000 --out "$OUT/dp.safetensors" --seed 0 --threads 1
