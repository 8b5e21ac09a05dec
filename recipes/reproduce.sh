#!/usr/bin/env bash
# Reproduce the paper's three experiments and their figures.
#
#   bash recipes/reproduce.sh [--scale cpu|paper] [--workers N] [--out DIR] [--figures DIR]
#                             [--backend local|ray] [--address RAY_ADDRESS]
#
# cpu (default): 57 runs (no-reward exploration 15, touch 21, fragile 21; 3 seeds; the lambda'_2
# sweep and ICM included) of 25k env frames each, 2 at a time: measured 52 min on the 2-core CPU
# (~243 env frames/s per process, 2026-11-25), inside the 2 h budget.
# paper: the same grids at the paper's scale (500k frames, batch 256, 1M buffer, ...); about 1 h
# per run on this CPU, so plan for a cluster or days.
#
# --backend ray runs each grid point as a Ray task (a local Ray with --workers CPUs, or the cluster
# at --address; --out must then be shared by every node, see docs/DISTRIBUTED.md).
# Resumable: finished runs (DONE) are skipped, interrupted ones continue from their checkpoint.
set -euo pipefail
cd "$(dirname "$0")/.."

scale=cpu workers=2 out=runs/reproduce figures=docs/figures backend=local address=()
while [ $# -gt 0 ]; do
  case "$1" in
    --scale) scale="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --figures) figures="$2"; shift 2 ;;
    --backend) backend="$2"; shift 2 ;;
    --address) address=(--address "$2"); shift 2 ;;
    *) echo "unknown argument: $1 (expected --scale, --workers, --out, --figures, --backend, --address)" >&2; exit 2 ;;
  esac
done

case "$scale" in
  cpu) extra=(--set collector.total_frames=25000 --set logging.eval_every_frames=5000
       --set logging.eval_episodes=5) ;;
  paper) extra=() ;;
  *) echo "--scale must be cpu or paper, got $scale" >&2; exit 2 ;;
esac

start=$(date +%s)
for sweep in fig3_noreward_impacts fig4_touch fig4_fragile; do
  python -m gentlerl.sweeps "recipes/sweeps/$sweep.yaml" --scale "$scale" --workers "$workers" \
    --backend "$backend" "${address[@]}" --out "$out/$scale" --set logging.wandb_mode=disabled \
    --set logging.progress=false "${extra[@]}"
  python -m gentlerl.plot "$out/$scale/$sweep" -o "$figures/$scale/$sweep"
done
echo "reproduction ($scale) took $(( ($(date +%s) - start) / 60 )) min; figures in $figures/$scale"
