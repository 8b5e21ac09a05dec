#!/usr/bin/env bash
# GentleBench: the method on dm_control contact tasks nobody here wrote, the force read in the unit
# of the force-tolerance rule (docs/log/GENTLEBENCH.md: criteria, rule, results).
#
#   bash experiments/gentlebench/grid.sh [--workers N] [--out DIR] [--figures DIR] [--episodes N]
#                                     [--tasks finger_turn_easy,finger_spin,hopper_stand] [--only KEY=V1,V2 ...]
#                                     [--set KEY=VALUE ...]  (config overrides on every run, e.g. Method II:
#                                     --set gentleness.surprise_kind=information_gain
#                                     --set network.penalty_surprise_bound=3 --out runs/gentlebench-method2)
#
# Grids: experiments/gentlebench/sweeps/gentlebench_<task>.yaml, each `r`, `r+rf`, `r+rf+rsp` x seeds
# 0-2 at 30k env steps (30 episodes of 1000 steps; 5k random first, the curiosity rewards on after
# 1k model updates, as the hand's cpu grids). Each file's env.force_scale is what
# `gentlerl forces dm_control:<task> --episodes 20` prints for the rule. Then each final actor on
# --episodes noise-free episodes (`gentlerl evaluate`, seed 0), each variant's seed-0 critics on
# `gentlerl calibration`, the figures and summary table of `gentlerl plot`, and the table with the
# pre-registered verdicts (`python experiments/gentlebench/table.py`).
# Resumable: finished runs (DONE) are skipped; evaluations and calibrations are redone.
set -euo pipefail
cd "$(dirname "$0")/../.."

workers=2 out=runs/gentlebench figures=figs/gentlebench episodes=10 only=() sets=()
tasks=finger_turn_easy,finger_spin,hopper_stand
while (($#)); do
  case "$1" in
    --workers) workers=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --figures) figures=$2; shift 2 ;;
    --episodes) episodes=$2; shift 2 ;;
    --tasks) tasks=$2; shift 2 ;;
    --only) only+=(--only "$2"); shift 2 ;;
    --set) sets+=(--set "$2"); shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done

for task in ${tasks//,/ }; do
  gentlerl sweep "experiments/gentlebench/sweeps/gentlebench_$task.yaml" --workers "$workers" \
    --out "$out" --set logging.progress=false --set logging.wandb_mode=disabled \
    --set logging.checkpoint_buffer=false --set logging.checkpoint_every_frames=10000 \
    "${sets[@]}" "${only[@]}"
done
for task in ${tasks//,/ }; do
  for run in "$out/gentlebench_$task"/*/; do
    [ -f "$run/DONE" ] || continue
    gentlerl evaluate "$run/checkpoint.pt" --episodes "$episodes" --json \
      --episodes-csv "$run/final_eval_episodes.csv" > "$run/final_eval.json"
    case "$run" in
      *_seed-0_*) gentlerl calibration "$run" --episodes 5 --json "$run/calibration.json" \
        > "$run/calibration.txt" ;;
    esac
  done
  gentlerl plot "$out/gentlebench_$task" -o "$figures/$task"
done
python experiments/gentlebench/table.py "$out"
