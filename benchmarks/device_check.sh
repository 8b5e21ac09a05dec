#!/usr/bin/env bash
# The GPU machine's check, in one command of at most 8 minutes: the machine (GPU, driver, torch,
# CUDA), the learner (eager vs CUDA graph vs compiled, 1 vs 5 seeds, with and without the penalty
# ensemble, paper scale), the replay's sample + priority update (CPU vs GPU storage), collection
# (1, 4 and 16 worker processes) and a short end-to-end training run with the learner and its
# replay on the GPU; on request (section group, not in the default 8 minutes) the same short run
# as a seed group of 5 seeds (its seed-updates/s against e2e's one seed);
# a dated markdown table goes to OUT_DIR/device_table.md (append it to benchmarks/RESULTS.md).
#
#   bash benchmarks/device_check.sh [OUT_DIR] [SECTION ...]    SECTION: env learner replay collect e2e group
#   LEARNER_MODES="cudagraphs" LEARNER_LIMIT=120 E2E_FRAMES=25000 E2E_LIMIT=150 bash ... (a shorter check)
#
# Packages: the machine's own python3 (torch with CUDA); what it lacks (torchrl, tensordict,
# dm_control, mujoco, the Shadow Hand model, hydra) comes from .devsite/site.tgz (or SITE_TGZ)
# when present (CONTRIBUTING.md, "A lent GPU machine", says how to build it), unpacked into a
# private temporary folder removed on exit, else from the environment.
# Each section has its own time limit, so a slow one cannot cost the others their numbers.
# A relative OUT_DIR is taken from the folder the script is run in. An option (-x), an unknown
# SECTION, an OUT_DIR that is a link or another user's, and a device_table.md or
# device_log.txt there that is a link or not a regular file are refused in one line (exit 2 / 1).
set -uo pipefail
OUT_DIR="${1:-${OUT:-/tmp/device_check}}"
case "$OUT_DIR" in
  -*) echo "device_check: '$OUT_DIR' is not an OUT_DIR (it takes no options; usage: bash benchmarks/device_check.sh [OUT_DIR] [SECTION ...])" >&2; exit 2 ;;
  /*) ;;
  *) OUT_DIR="$PWD/$OUT_DIR" ;;  # relative to where it was run, not to the checkout it moves to
esac
cd "$(dirname "$0")/.." || exit 1
shift || true
SECTIONS="${*:-env learner replay collect e2e}"
for section in $SECTIONS; do
  case "$section" in
    env | learner | replay | collect | e2e | group) ;;
    *) echo "device_check: unknown section '$section' (expected env learner replay collect e2e group)" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT_DIR" || exit 1
# OUT_DIR may sit in a shared folder (/tmp): another user's folder, or a table or log planted
# there as a link, would have this script write where they point.
if [ -L "$OUT_DIR" ] || [ ! -O "$OUT_DIR" ]; then
  echo "device_check: OUT_DIR '$OUT_DIR' must be a folder of this user's, not a link or another's" >&2
  exit 1
fi
TABLE="$OUT_DIR/device_table.md"
LOG="$OUT_DIR/device_log.txt"
for file in "$TABLE" "$LOG"; do
  if [ -L "$file" ] || { [ -e "$file" ] && [ ! -f "$file" ]; }; then
    echo "device_check: '$file' is a link or not a regular file; remove it first" >&2
    exit 1
  fi
done
# Private scratch (the unpacked packages, the e2e runs), removed on exit; the table is written
# to a temporary file in OUT_DIR and renamed over device_table.md, so a link there is replaced,
# never written through.
WORK="$(mktemp -d "${TMPDIR:-/tmp}/gentlerl_device_check.XXXXXX")" || exit 1
TABLE_PART="$(mktemp "$OUT_DIR/.device_table.XXXXXX")" || { rm -rf "$WORK"; exit 1; }
chmod 644 "$TABLE_PART"
finish() {
  [ -s "$TABLE_PART" ] && mv -f "$TABLE_PART" "$TABLE"
  rm -f "$TABLE_PART"
  rm -rf "$WORK"
}
trap finish EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
PY="${PYTHON:-python3}"
SITE_TGZ="${SITE_TGZ:-.devsite/site.tgz}"
export PYTHONPATH="$PWD/src:$PWD/benchmarks"
if ! "$PY" -c "import torchrl, dm_control" 2>/dev/null && [ -f "$SITE_TGZ" ]; then
  mkdir -m 700 "$WORK/site" && tar xzf "$SITE_TGZ" -C "$WORK/site" || exit 1
  export PYTHONPATH="$WORK/site:$PYTHONPATH"
fi
export MUJOCO_GL="${MUJOCO_GL:-disable}" RL_WARNINGS=False PYTHONUNBUFFERED=1

# run LIMIT_S NAME CMD...: the command's output to the log; its table lines to the table
run() {
  local limit=$1 name=$2
  shift 2
  echo "--- $name ($(date -u +%H:%M:%S), limit ${limit} s): $*" | tee -a "$LOG"
  local start=$SECONDS
  timeout "$limit" "$@" >>"$LOG" 2>&1
  local rc=$?
  echo "--- $name: rc $rc in $((SECONDS - start)) s" | tee -a "$LOG"
  { echo; echo "### $name (rc $rc, $((SECONDS - start)) s)"; echo
    sed -n "/^=== $name/,\$p" "$LOG" | grep -E '^\|' || true; } >>"$TABLE_PART"
}

echo "## device_check, $(date -u '+%Y-%m-%d %H:%M UTC')" >"$TABLE_PART"
if [[ " $SECTIONS " == *" env "* ]]; then
  {
    echo
    echo '```'
    nvidia-smi -L 2>&1
    nvidia-smi --query-gpu=driver_version,clocks.sm,clocks.mem,memory.used,utilization.gpu --format=csv 2>&1
    "$PY" -c "import sys, torch; print('python', sys.version.split()[0], '| torch', torch.__version__, '| CUDA', torch.version.cuda, '| GPU', torch.cuda.get_device_name() if torch.cuda.is_available() else 'none')" 2>&1
    "$PY" -c "import tensordict, torchrl, mujoco, dm_control, gentlerl; print('tensordict', tensordict.__version__, '| torchrl', torchrl.__version__, '| mujoco', mujoco.__version__)" 2>&1 | tail -1
    echo "CPUs $(nproc), $(uptime)"
    echo '```'
  } >>"$TABLE_PART"
fi
if [[ " $SECTIONS " == *" learner "* ]]; then
  echo "=== learner" >>"$LOG"
  run "${LEARNER_LIMIT:-240}" learner "$PY" benchmarks/learner_graphs.py --device cuda --scale paper --seeds 1 5 --models \
    --modes ${LEARNER_MODES:-eager cudagraphs compile+cudagraphs} --min-time 1.5 --json "$OUT_DIR/learner.json"
fi
if [[ " $SECTIONS " == *" replay "* ]]; then
  echo "=== replay" >>"$LOG"
  run 60 replay "$PY" benchmarks/replay_device.py --devices cpu cuda --min-time 1.5 \
    --json "$OUT_DIR/replay.json"
fi
if [[ " $SECTIONS " == *" collect "* ]]; then
  echo "=== collect" >>"$LOG"
  run 100 collect "$PY" benchmarks/collect_scale.py --workers 1 4 16 --hands 4 --batches 8 \
    --json "$OUT_DIR/collect.json"
fi
if [[ " $SECTIONS " == *" e2e "* ]]; then
  echo "=== e2e" >>"$LOG"
  E2E_RUN="$WORK/e2e_run"  # not under OUT_DIR: a finished run's checkpoint is large
  run "${E2E_LIMIT:-200}" e2e "$PY" benchmarks/e2e_speed.py --device cuda --graphs --replay-on-device --workers 12 --threads 2 \
    --frames "${E2E_FRAMES:-30000}" --run-dir "$E2E_RUN" --json "$OUT_DIR/e2e.json"
  if [ ! -f "$OUT_DIR/e2e.json" ]; then  # stopped by its limit: its rates up to there
    echo "=== e2e_stopped" >>"$LOG"
    run 60 e2e_stopped "$PY" benchmarks/e2e_speed.py --from-logs "$E2E_RUN" --random-frames 10000
  fi
fi
if [[ " $SECTIONS " == *" group "* ]]; then
  echo "=== group" >>"$LOG"
  GROUP_RUN="$WORK/group_run"
  run "${GROUP_LIMIT:-200}" group "$PY" benchmarks/e2e_speed.py --device cuda --graphs --replay-on-device --workers 3 --threads 2 \
    --seeds 5 --frames "${GROUP_FRAMES:-20000}" --run-dir "$GROUP_RUN" --json "$OUT_DIR/group.json"
  if [ ! -f "$OUT_DIR/group.json" ]; then
    echo "=== group_stopped" >>"$LOG"
    run 60 group_stopped "$PY" benchmarks/e2e_speed.py --from-logs "$GROUP_RUN/seed0" --seeds 5 --random-frames 10000
  fi
fi
cat "$TABLE_PART"
