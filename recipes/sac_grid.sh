#!/usr/bin/env bash
# The SAC grid of docs/SAC.md: r and r+rf+rsp on touch and fragile, seeds 0-2, 30k frames each,
# two runs at a time (one torch thread each), then the table. Re-running skips finished runs.
# Usage: bash recipes/sac_grid.sh [--out DIR] [--workers N]
set -euo pipefail
out=runs/sac workers=2
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    *) echo "unknown argument: $1 (expected --out DIR or --workers N)" >&2; exit 2 ;;
  esac
done
here="$(cd "$(dirname "$0")" && pwd)"
runs=()
for task in touch fragile; do
  lam="[2,2]"; [ "$task" = fragile ] && lam="[2,1.5]"
  for variant in r r+rf+rsp; do
    for seed in 0 1 2; do
      dir="$out/$task/$variant/seed$seed"
      [ -f "$dir/final_eval.json" ] && continue
      runs+=("task=$task variant=$variant seed=$seed lam_prime=$lam run_dir=$dir")
    done
  done
done
if [ ${#runs[@]} -gt 0 ]; then
  printf '%s\n' "${runs[@]}" | xargs -P "$workers" -I{} sh -c \
    "python '$here/sac_gentle.py' {} > /dev/null 2>&1 || echo 'failed: {}' >&2"
fi
python "$here/sac_table.py" "$out"
