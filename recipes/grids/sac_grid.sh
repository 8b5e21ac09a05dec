#!/usr/bin/env bash
# The SAC grid of docs/SAC.md: r and r+rf+rsp on touch and fragile, seeds 0-2, 30k frames each,
# two runs at a time (one torch thread each), then the table with the pre-registered verdicts
# (`gentlerl table sac`). Re-running skips finished runs.
# Usage: bash recipes/grids/sac_grid.sh [--out DIR] [--workers N]
# Not `gentlerl sweep`: a sweep's points are `gentlerl-train` runs, their keys TrainConfig fields
# (checked against it before anything runs); recipes/sac_gentle.py is another program with its
# own settings (SACConfig: lam_prime, total_frames, ...), so this loop runs its grid instead.
set -euo pipefail
out=runs/sac workers=2
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    *) echo "unknown argument: $1 (expected --out DIR or --workers N)" >&2; exit 2 ;;
  esac
done
case "$workers" in
  '' | *[!0-9]* | 0) echo "--workers must be a positive integer, got '$workers'" >&2; exit 2 ;;
esac
here="$(cd "$(dirname "$0")" && pwd)"
failed=0
# Each run's arguments stay separate words (no shell re-reads --out); its output goes to
# DIR.log, and a failure is reported with that log's last line.
for task in touch fragile; do
  lam="[2,2]"; [ "$task" = fragile ] && lam="[2,1.5]"
  for variant in r r+rf+rsp; do
    for seed in 0 1 2; do
      dir="$out/$task/$variant/seed$seed"
      [ -f "$dir/final_eval.json" ] && continue
      while [ "$(jobs -rp | wc -l)" -ge "$workers" ]; do wait -n || failed=1; done
      mkdir -p -- "$(dirname -- "$dir")"
      (
        python "$here/../sac_gentle.py" "task=$task" "variant=$variant" "seed=$seed" \
          "lam_prime=$lam" "run_dir=$dir" >"$dir.log" 2>&1 ||
          { echo "failed: $dir: $(tail -n 1 -- "$dir.log")" >&2; exit 1; }
      ) &
    done
  done
done
while [ "$(jobs -rp | wc -l)" -gt 0 ]; do wait -n || failed=1; done
python -m gentlerl table sac "$out"
exit "$failed"
