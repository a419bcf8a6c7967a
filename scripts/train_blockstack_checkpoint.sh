#!/usr/bin/env bash
# Reproduce the shipped BlockStack skill policy (baselines/checkpoints/blockstack/dp.*).
#
# 1. the random planner's skill data, branched: 100 episode seeds x 4 skills, and from each skill's
#    start state 3 alternative skills the planner could have chosen there (steer-bench suite
#    itps-blockstack-data, one shard per seed, resumable; ~12 min on two workers);
# 2. the plan data set: one (32 x [x, y, z, gripper]) plan per successful skill, each also with the
#    cubes listed in 15 other orders and the scene shifted (<= 5 cm) and turned (<= 0.5 rad)
#    (python -m steer_envs.data.blockstack_shards);
# 3. the Diffusion Policy, preset `blockstack` with 2 Fourier octaves of the observation
#    (--model obs_octaves=2: less room to memorise scenes), fused AdamW, seed 0, ONE torch thread
#    (bit-identical for the same thread count, torch version and CPU kind; ~32 min). In all ~44 min.
#
# Usage: scripts/train_blockstack_checkpoint.sh [--check] [DATA_DIR]   (default: runs/blockstack-data)
#   --check  build (or reuse) the data, then re-run only the first 200 training steps and compare
#            the loss curve with the shipped record; exit 1 if it differs.
# WORKERS=N sets the data job's parallel workers (default 2); CHECKPOINT_DIR=DIR writes the new
# checkpoint there instead of over the shipped one (to compare with it: cmp, or --check its record).
# POLICY=flow trains the flow-matching policy of the same preset on the same data instead (flow.*; the
# matched comparison of itps-blockstack's `policy=flow`).
source "$(dirname "$0")/recipe.sh"
recipe_args runs/blockstack-data "$@"
EPISODES=100
SKILLS=4
BRANCHES=3
DATA="$DATA_DIR/blockstack-plans-${EPISODES}x${SKILLS}b${BRANCHES}.npz"
SHIPPED=baselines/checkpoints/blockstack
OUT=${CHECKPOINT_DIR:-$SHIPPED}

export MUJOCO_GL=${MUJOCO_GL:-osmesa}
"$PY" -m steer_envs.bench run itps-blockstack-data --seeds "$EPISODES" --workers "${WORKERS:-2}" \
    --param "cache_dir=$DATA_DIR" --param "skills_per_episode=$SKILLS" --param "branches=$BRANCHES" \
    --out "$DATA_DIR/run"
"$PY" -m steer_envs.data.blockstack_shards --cache-dir "$DATA_DIR" --episodes "$EPISODES" \
    --skills-per-episode "$SKILLS" --branches "$BRANCHES" --permutations 15 --shift 0.05 --yaw 0.5 --out "$DATA"
POLICY=${POLICY:-dp}
if [ "$CHECK" = 1 ]; then
  exec "$PY" -m steer_envs.baselines.training --policy "$POLICY" --dataset "$DATA" \
      --check "$SHIPPED/$POLICY.json" --check-steps 200
fi
mkdir -p "$OUT"
"$PY" -m steer_envs.baselines.training --policy "$POLICY" --preset blockstack --dataset "$DATA" \
    --model obs_octaves=2 --fused-optimizer --out "$OUT/$POLICY.safetensors" --seed 0 --threads 1
echo "recipe done in $((SECONDS / 60)) min $((SECONDS % 60)) s: $OUT/$POLICY.safetensors"
