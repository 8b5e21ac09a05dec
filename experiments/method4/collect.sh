#!/bin/bash
# Copy a Method IV suite's results into the repository: results.csv and, per run, its config, its
# final evaluation's episodes and the few curves the verdict draws (small CSVs only; checkpoints
# and the other scalars stay in runs/).
#   experiments/method4/collect.sh SUITE [RUNS_DIR]   # SUITE: hand, replay or foreign
set -euo pipefail
suite=${1:?usage: collect.sh SUITE [RUNS_DIR]}
case $suite in hand|replay|foreign) ;; *) echo "collect.sh: SUITE must be hand, replay or foreign, got '$suite'" >&2; exit 2;; esac
cd "$(dirname "$0")/../.."
src=${2:-runs/method4/$suite}
dst=experiments/method4/$suite
[ -f "$src/results.csv" ] || { echo "collect.sh: no $src/results.csv" >&2; exit 1; }
mkdir -p "$dst"
cp "$src/results.csv" "$dst/results.csv"
for run in "$src"/*/*/seed*; do
  [ -f "$run/DONE" ] || continue  # a run still training (its in-loop evaluations are partial)
  rel=${run#"$src"/}
  mkdir -p "$dst/$rel"
  cp "$run/eval_episodes.csv" "$run/config.yaml" "$dst/$rel/"
  for f in eval/success_rate eval/max_impact_mean eval/return eval/cost train/lagrange_multiplier train/episode_cost; do
    if [ -f "$run/logs/scalars/$f.csv" ]; then
      mkdir -p "$dst/$rel/$(dirname $f)"
      cp "$run/logs/scalars/$f.csv" "$dst/$rel/$f.csv"
    fi
  done
done
du -sh "$dst"
