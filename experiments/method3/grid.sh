#!/usr/bin/env bash
# Method III grid (docs/log/GENTLEBENCH.md, "Method III amendment": criteria written before the runs):
# per task, `r` and the paper's `r+rf+rsp` under the stated tolerance, then the steered pair
# (gentleness.multiplier=pid, curiosity_norm=true): `r+rf` (the constrained baseline) and
# `r+rf+rsp` (the new method); 3 seeds, 30k env steps, one setting for every task (only the
# tolerance differs, in each sweep file). Then each final actor on --episodes noise-free episodes
# (`gentlerl evaluate`, seed 0) and the table (`python experiments/method3/table.py`).
#
#   bash experiments/method3/grid.sh [--workers N] [--out DIR] [--episodes N]
#                                 [--tasks finger_turn_easy,finger_spin,touch,fragile]
#                                 [--kinds ,_steered] [--frames N]
# --kinds picks the sweep files per task (method3_<task><kind>.yaml): "" the unsteered pair,
# _steered the first amendment's steered pair, _paced the second amendment's (touch, fragile),
# _normonly and _pidonly the third amendment's (each mechanism alone on r+rf+rsp), _deployed the
# fourth's pair (a plain Lagrangian on the deployed policy's episodes), _deployedw1 its
# attribution row (the same with the paper's weight as floor), the fifth's candidate on the fingers.
# _t394* the sixth's finger-spin at a tolerance the task admits, _budget its finger-turn_easy `r`.
# Budget: 30k env steps per run; finger_spin 50k (where `r` learns it, docs/log/FINGER.md);
# --frames N: N for every task (the sixth amendment's budget probe).
# Resumable: finished runs (DONE) are skipped; evaluations are redone.
set -euo pipefail
cd "$(dirname "$0")/../.."

workers=2 out=runs/method3 episodes=10 tasks=finger_turn_easy,touch,fragile kinds=,_steered frames=
while (($#)); do
  case "$1" in
    --workers) workers=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --episodes) episodes=$2; shift 2 ;;
    --tasks) tasks=$2; shift 2 ;;
    --kinds) kinds=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done

if [ -n "$frames" ] && ! [[ "$frames" =~ ^[1-9][0-9]*$ ]]; then
  echo "method3.sh: --frames must be a positive integer, got '$frames'" >&2
  exit 2
fi
IFS=, read -r -a kind_list <<< "$kinds,"  # the trailing comma keeps a leading empty kind
for kind in "${kind_list[@]}"; do  # before any run: a kind no task has is a typo
  found=0
  for task in ${tasks//,/ }; do
    [ -f "experiments/method3/sweeps/method3_$task$kind.yaml" ] && found=1
  done
  if [ "$found" = 0 ]; then
    echo "method3.sh: --kinds '$kind' names no sweep file of the tasks $tasks" >&2
    exit 2
  fi
done

budget=(--set collector.init_random_frames=5000
  --set gentleness.reward_delay=1000 --set logging.eval_episodes=5
  --set logging.checkpoint_buffer=false --set logging.checkpoint_every_frames=10000
  --set logging.progress=false --set logging.wandb_mode=disabled)
for task in ${tasks//,/ }; do
  case "$task" in
    touch|fragile) per=(--set logging.eval_every_frames=5000 --set collector.num_envs=1) ;;
    *) per=(--set logging.eval_every_frames=10000) ;;
  esac
  budget_frames=30000
  [ "$task" = finger_spin ] && budget_frames=50000
  per+=(--set "collector.total_frames=${frames:-$budget_frames}")
  for kind in "${kind_list[@]}"; do
    sweep="experiments/method3/sweeps/method3_$task$kind.yaml"
    if [ ! -f "$sweep" ]; then  # e.g. _pidonly exists for the hand's tasks only
      echo "method3.sh: no $sweep: $task has no '$kind' runs, skipped" >&2
      continue
    fi
    gentlerl sweep "$sweep" --workers "$workers" --out "$out" "${budget[@]}" "${per[@]}"
  done
done
for task in ${tasks//,/ }; do
  for run in "$out/method3_$task"*/*/; do
    [ -f "$run/DONE" ] || continue
    gentlerl evaluate "$run/checkpoint.pt" --episodes "$episodes" --json \
      --episodes-csv "$run/final_eval_episodes.csv" > "$run/final_eval.json"
  done
done
python experiments/method3/table.py "$out"
