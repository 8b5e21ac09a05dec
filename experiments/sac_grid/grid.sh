#!/usr/bin/env bash
# The SAC grid of docs/log/SAC.md: r and r+rf+rsp on touch and fragile, seeds 0-2, 30k frames each,
# two runs at a time (one torch thread each), then the table with the pre-registered verdicts
# (`python experiments/sac_grid/table.py`). Re-running skips finished runs.
# Usage: bash experiments/sac_grid/grid.sh [--out DIR] [--workers N] [--tasks "touch fragile"]
#                                       [--variants "r r+rf+rsp"] [--utd R]
# --variants also takes Method III's rows (docs/log/SAC.md, Method III amendment): `new` (r+rf+rsp
# with the PID Lagrangian on the actor's noise-free episodes at the tolerance T = 2 N, w = mu),
# `new_w1` (the same with the paper's weight as floor, w = 1 + mu: the fifth amendment's
# candidate) and `baseline` (r+rf with new's); --utd sets the recipe's utd_ratio.
# Not `gentlerl sweep`: a sweep's points are `gentlerl-train` runs, their keys TrainConfig fields
# (checked against it before anything runs); recipes/sac_gentle.py is another program with its
# own settings (SACConfig: lam_prime, total_frames, ...), so this loop runs its grid instead.
set -euo pipefail
out=runs/sac workers=2 tasks="touch fragile" variants="r r+rf+rsp" utd=""
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --tasks) tasks="$2"; shift 2 ;;
    --variants) variants="$2"; shift 2 ;;
    --utd) utd="$2"; shift 2 ;;
    *) echo "unknown argument: $1 (expected --out, --workers, --tasks, --variants or --utd)" >&2
       exit 2 ;;
  esac
done
case "$workers" in
  '' | *[!0-9]* | 0) echo "--workers must be a positive integer, got '$workers'" >&2; exit 2 ;;
esac
steered=(tolerance=2.0 multiplier=pid multiplier_period=1000 multiplier_integral_max=3.0
  multiplier_episodes=3)
here="$(cd "$(dirname "$0")" && pwd)"
failed=0
# Each run's arguments stay separate words (no shell re-reads --out); its output goes to
# DIR.log, and a failure is reported with that log's last line.
for task in $tasks; do
  lam="[2,2]"; [ "$task" = fragile ] && lam="[2,1.5]"
  for variant in $variants; do
    case "$variant" in
      new) args=(variant=r+rf+rsp "${steered[@]}" multiplier_base=0.0) ;;
      new_w1) args=(variant=r+rf+rsp "${steered[@]}" multiplier_base=1.0) ;;
      baseline) args=(variant=r+rf "${steered[@]}" multiplier_base=0.0) ;;
      *) args=("variant=$variant") ;;
    esac
    [ -n "$utd" ] && args+=("utd_ratio=$utd")
    for seed in 0 1 2; do
      dir="$out/$task/$variant/seed$seed"
      [ -f "$dir/final_eval.json" ] && continue
      while [ "$(jobs -rp | wc -l)" -ge "$workers" ]; do wait -n || failed=1; done
      mkdir -p -- "$(dirname -- "$dir")"
      (
        python "$here/../../recipes/sac_gentle.py" "task=$task" "${args[@]}" "seed=$seed" \
          "lam_prime=$lam" "run_dir=$dir" >"$dir.log" 2>&1 ||
          { echo "failed: $dir: $(tail -n 1 -- "$dir.log")" >&2; exit 1; }
      ) &
    done
  done
done
while [ "$(jobs -rp | wc -l)" -gt 0 ]; do wait -n || failed=1; done
python "$here/table.py" "$out"
exit "$failed"
