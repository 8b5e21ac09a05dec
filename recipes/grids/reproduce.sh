#!/usr/bin/env bash
# Reproduce the paper's three experiments, their figures and the final-policy evaluations that the
# pre-registered criteria of docs/log/REPRODUCTION.md judge.
#
#   bash recipes/grids/reproduce.sh [--scale cpu|paper] [--method METHOD] [--workers N]
#                                   [--out DIR] [--figures DIR] [--backend local|ray] [--address RAY_ADDRESS]
#                                   [--policies DIR]  (default docs/policies for cpu/changes)
#                                   [--only KEY=V1,V2 ...]  (part of each grid, e.g. --only seed=0,1)
#                                   [--sweeps NAME,NAME]  (some of the three grids, e.g. fig4_touch)
#
# Grids (default physics regime `paper`, docs/REGIMES.md):
#   --scale cpu (recipes/sweeps/cpu/): no-reward exploration `rs`, `rf+rs`, `rf+rsp` x 3 seeds
#     (9 runs); touch and fragile `r`, `r+rf`, `r+rf+rs`, `r+icm`, `r+rf+rsp` x 5 seeds (25 runs
#     each); the primary lambda'_2 only (2 for touch and no reward, 1.5 for fragile): 59 runs of
#     30k env frames, 5k of them random, intrinsic rewards on after 1k model updates (~9k frames).
#   --scale paper (recipes/sweeps/): the paper's grid, lambda'_2 in 3 values each: 85 runs of 500k
#     frames at the paper's hyper-parameters; about 1 h per run on a 2-core CPU, plan for a cluster.
# --method changes (default): the CPU-scale changes to the method (penalty support capped at 0,
# non-episodic intrinsic heads, dynamics surprise x 0.002, dense heads' supports spanning the
# discounted horizon, r^sp recomputed when sampled; no NLL floor since the fifth amendment, as
# the paper); --method published: the method as the paper gives it
# (gentleness.surprise_nll_floor=null network.bounded_support=false
# learner.episodic_intrinsic=true gentleness.dynamics_surprise_scale=1
# gentleness.rescore_surprise=false, and the paper's support (-100, 100) for every head:
# network.v_min=-100 network.v_max=100 network.dense_reward_bound=null). Both are needed for the
# two rows of each claim. The ablation methods switch off one change at a time from `changes`:
# no-support-cap (network.bounded_support=false), episodic (learner.episodic_intrinsic=true),
# unscaled-rs (gentleness.dynamics_surprise_scale=1), shared-support
# (network.dense_reward_bound=null: [v_min, v_max] = [-10, 10] for every head), no-recompute
# (gentleness.rescore_surprise=false: r^sp as stored at collection). no-nll-floor
# (gentleness.surprise_nll_floor=null) was the third amendment's ablation of the floor at 0 and is
# the same as `changes` today; nll-floor (gentleness.surprise_nll_floor=0) puts that floor back.
# Method II (docs/log/REPRODUCTION.md, ninth amendment): rsp-bound (network.penalty_surprise_bound=3:
# r^sp's head spans +-3 per step x the horizon), information-gain
# (gentleness.surprise_kind=information_gain: r^sp's curiosity is the penalty ensemble's
# disagreement), method2 (both).
#
# Wall clock, --scale cpu, 2 workers on a 2-core Xeon: see docs/log/REPRODUCTION.md (measured there).
#
# --backend ray runs each grid point as a Ray task (a local Ray with --workers CPUs, or the cluster
# at --address; --out must then be shared by every node, see docs/DISTRIBUTED.md).
# Resumable: finished runs (DONE) are skipped, interrupted ones continue from their checkpoint;
# final evaluations are redone (they take seconds per run).
set -euo pipefail
cd "$(dirname "$0")/../.."

scale=cpu method=changes workers=2 out=runs/reproduce figures=docs/figures backend=local address=() policies="" only=()
sweeps_run=fig3_noreward_impacts,fig4_touch,fig4_fragile
while [ $# -gt 0 ]; do
  case "$1" in
    --scale) scale="$2"; shift 2 ;;
    --method) method="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --figures) figures="$2"; shift 2 ;;
    --backend) backend="$2"; shift 2 ;;
    --address) address=(--address "$2"); shift 2 ;;
    --policies) policies="$2"; shift 2 ;;
    --only) only+=(--only "$2"); shift 2 ;;
    --sweeps) sweeps_run="$2"; shift 2 ;;
    *) echo "unknown argument: $1 (expected --scale, --method, --workers, --out, --figures," \
         "--backend, --address, --policies, --only, --sweeps)" >&2
       exit 2 ;;
  esac
done

case "$scale" in
  cpu) sweeps=recipes/sweeps/cpu
       extra=(--set collector.total_frames=30000 --set collector.init_random_frames=5000
       --set gentleness.reward_delay=1000 --set logging.eval_every_frames=5000
       --set logging.eval_episodes=5 --set logging.checkpoint_buffer=false) ;;
  paper) sweeps=recipes/sweeps extra=() ;;
  *) echo "--scale must be cpu or paper, got $scale" >&2; exit 2 ;;
esac
# The registered runs collected with one hand per collector (the default is 4 since 2026-12-02).
extra+=(--set collector.num_envs=1)
case "$method" in
  changes) ;;
  published) extra+=(--set gentleness.surprise_nll_floor=null --set network.bounded_support=false
                     --set learner.episodic_intrinsic=true
                     --set gentleness.dynamics_surprise_scale=1
                     --set gentleness.rescore_surprise=false
                     --set network.v_min=-100 --set network.v_max=100
                     --set network.dense_reward_bound=null) ;;
  shared-support) extra+=(--set network.dense_reward_bound=null) ;;
  no-recompute) extra+=(--set gentleness.rescore_surprise=false) ;;
  no-nll-floor) extra+=(--set gentleness.surprise_nll_floor=null) ;;
  nll-floor) extra+=(--set gentleness.surprise_nll_floor=0) ;;
  no-support-cap) extra+=(--set network.bounded_support=false) ;;
  episodic) extra+=(--set learner.episodic_intrinsic=true) ;;
  unscaled-rs) extra+=(--set gentleness.dynamics_surprise_scale=1) ;;
  rsp-bound) extra+=(--set network.penalty_surprise_bound=3) ;;
  information-gain) extra+=(--set gentleness.surprise_kind=information_gain) ;;
  method2) extra+=(--set network.penalty_surprise_bound=3
                   --set gentleness.surprise_kind=information_gain) ;;
  *) echo "--method must be changes, published, no-nll-floor, nll-floor, no-support-cap, episodic," \
       "unscaled-rs, shared-support, no-recompute, rsp-bound, information-gain or method2," \
       "got $method" >&2; exit 2 ;;
esac
for sweep in ${sweeps_run//,/ }; do
  case "$sweep" in
    fig3_noreward_impacts|fig4_touch|fig4_fragile) ;;
    *) echo "--sweeps takes fig3_noreward_impacts, fig4_touch, fig4_fragile; got $sweep" >&2
       exit 2 ;;
  esac
done

# The repository ships the default row (cpu scale, CPU-scale changes) as docs/policies/.
if [ -z "$policies" ]; then
  if [ "$scale/$method" = cpu/changes ]; then policies=docs/policies
  else policies="docs/policies/$scale/$method"; fi
fi
start=$(date +%s)
dir="$out/$scale/$method"
for sweep in ${sweeps_run//,/ }; do
  python -m gentlerl sweep "$sweeps/$sweep.yaml" --scale "$scale" --workers "$workers" \
    --backend "$backend" "${address[@]}" --out "$dir" --set logging.wandb_mode=disabled \
    --set logging.progress=false "${extra[@]}" "${only[@]}"
  # The criteria's "final success": each run's last actor, 20 deterministic episodes; their rows
  # (final_eval_episodes.csv in each run) are Fig. 5's data, so they come before the figures.
  mkdir -p "$figures/$scale/$method/$sweep"
  evals="$figures/$scale/$method/$sweep/final_eval.jsonl"
  : > "$evals"
  find "$dir/$sweep" -name checkpoint.pt | sort | xargs -P "$workers" -I{} sh -c \
    'python -m gentlerl evaluate "$1" --episodes 20 --seed 0 --json \
       --episodes-csv "$(dirname "$1")/final_eval_episodes.csv"' _ {} >> "$evals"
  python -m gentlerl plot "$dir/$sweep" -o "$figures/$scale/$method/$sweep"
  # Shipped policies: the final actor of each touch / fragile run (r+rf+rsp at the primary
  # lambda'_2 of docs/log/REPRODUCTION.md) as $policies/<task>/<variant>/seed<k>.pt.
  # The no-reward grid trains no task policy to ship.
  if [ "$sweep" != fig3_noreward_impacts ]; then
    python -m gentlerl export "$dir/$sweep" --out "$policies"
  fi
done
python -m gentlerl claims "$dir" --final-evals "$figures/$scale/$method" \
  --markdown "$figures/$scale/$method/claims.md"
echo "reproduction ($scale, $method) took $(( ($(date +%s) - start) / 60 )) min;" \
  "figures in $figures/$scale/$method"
