#!/usr/bin/env bash
# Gentleness beyond the hand: dm_control's finger-spin (TorchRL DMControlEnv) with the task reward
# only (r), with the impact penalty (r+rf) and with penalty surprise (r+rf+rsp), 3 seeds each.
#
#   bash experiments/finger_spin/grid.sh [--workers N] [--out DIR] [--figures DIR] [--only KEY=V1,V2 ...]
#
# The grid is experiments/finger_spin/finger_spin.yaml: 9 runs of 50k env steps (10k random first),
# ~14 min each on one core of a busy 2-core machine (62 env steps/s, r+rf+rsp), ~1-1.5 h with
# --workers 2. Criteria and results: docs/log/FINGER.md. The env, its force and its observation come from the config alone:
#   env.name=dm_control:finger-spin    TorchRL's DMControlEnv("finger", "spin"), cast to float32
#   env.force_adapter (null)           dm_control_touch: force = expm1(touch) [2, 1] N
#   env.observation_keys (null)        position [4], velocity [3], touch [2] -> observation [9]
# One run by hand:
#   gentlerl train env.name=dm_control:finger-spin variant=r+rf+rsp seed=0 \
#     collector.total_frames=50000 logging.eval_episodes=5 logging.eval_every_frames=10000 run_dir=runs/finger_spin/r+rf+rsp/seed0
# Finger-spin has no success / broken outcome: evaluations are ranked by return, and the
# summary's rows give each variant's return and its per-episode max impact (N).
set -euo pipefail
cd "$(dirname "$0")/../.."

workers=2 out=runs/sweeps figures=figs/finger_spin only=()
while (($#)); do
  case "$1" in
    --workers) workers=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --figures) figures=$2; shift 2 ;;
    --only) only+=(--only "$2"); shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done

gentlerl sweep experiments/finger_spin/finger_spin.yaml --workers "$workers" --out "$out" \
  --figures "$figures" "${only[@]}"
# The final actors on 20 noise-free episodes each, read by gentlerl plot as the final policy's.
for run in "$out"/finger_spin/*/; do
  gentlerl evaluate "$run/checkpoint.pt" --episodes 20 --episodes-csv "$run/final_eval_episodes.csv"
done
gentlerl plot "$out/finger_spin" -o "$figures"
