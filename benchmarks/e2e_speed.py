"""End-to-end training speed: one short run of ``gentlerl train`` at the paper's scale, timed.

    python benchmarks/e2e_speed.py [--task fragile] [--frames 30000] [--random-frames 10000]
        [--device cuda] [--graphs] [--replay-on-device] [--workers 8] [--threads 4]
        [--seeds 5] [--run-dir D] [--json F]
    python benchmarks/e2e_speed.py --from-logs D --random-frames 10000   (a stopped run's rates)

The run is the paper preset (``scale=paper``: batch 256, critics 400-300, one update per frame)
with the learner on ``--device`` (``--graphs``: ``learner.compile`` + ``learner.cudagraphs``;
``--replay-on-device``: ``replay.device=learner``, the replay and its priority trees there too),
collection by ``--workers`` env processes (TorchRL's ``MultiSyncCollector``; 1: the single
collector with 4 hands), no checkpoint and one 5-episode evaluation. It reports the run's wall
clock, frames/s over the run, the loop's own ``train/updates_per_s`` (model + learner updates,
sampling and priorities; collection excluded) after the random frames, and the time a 500k-frame
run would take at those rates (``init_random_frames`` at the random-phase rate, the rest at the
learning rate): the measured floor of the paper-scale goal. ``--seeds S`` (> 1) trains seeds
0 .. S-1 as one seed group (``gentlerl seeds``: their updates one batched step, each seed its own
collector of ``--workers``) and reads the rates of seed 0's run (the group's: every seed takes
the same updates), with ``seed_updates_per_s`` = S x the loop's. The loop logs (and flushes) its
scalars every 100 updates, so a run stopped by a time limit (``--run-dir`` keeps its logs) still
gives its rates up to where it stopped: ``--from-logs`` reads them without training.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from gentlerl.analysis.runs import load_run
from gentlerl.training import make_config, train, train_seeds

PAPER_FRAMES = 500_000


def run(args: argparse.Namespace, run_dir: Path) -> dict:
    """Train once as the module says; the row of :func:`rates` with the run's wall clock."""
    collector = {"total_frames": args.frames, "init_random_frames": args.random_frames}
    if args.workers > 1:
        collector |= {"kind": "multi", "num_workers": args.workers, "num_envs": 1}
        collector["frames_per_batch"] = 50 * args.workers
    learner = {"device": args.device, "compile": args.graphs, "cudagraphs": args.graphs}
    settings = dict(
        task=args.task,
        num_threads=args.threads,
        collector=collector,
        learner=learner,
        replay={"device": "learner" if args.replay_on_device else "cpu"},
        logging={
            "eval_every_frames": 10**9,
            "checkpoint_every_frames": 10**9,
            "eval_episodes": 5,
            "progress": False,
            "log_every_updates": 100,
        },
    )
    start = time.perf_counter()
    if args.seeds > 1:  # a seed group: seed k in run_dir/seed<k>, the rates of seed 0's run
        cfgs = [
            make_config("paper", seed=k, run_dir=str(run_dir / f"seed{k}"), **settings)
            for k in range(args.seeds)
        ]
        summary = train_seeds(cfgs)[0]
        run_dir = run_dir / "seed0"
    else:
        summary = train(make_config("paper", seed=args.seed, run_dir=str(run_dir), **settings))
    wall = time.perf_counter() - start
    return rates(run_dir, args.random_frames, args.seeds) | {
        "wall_s": wall,
        "final_success": summary.get("success_rate"),
    }


def rates(run_dir: Path, random_frames: int, seeds: int = 1) -> dict:
    """A (finished or stopped) run's rates from its logged ``train/wall_s`` and
    ``train/updates_per_s``: frames/s while random and while learning, the loop's median
    updates/s (times ``seeds``: the seed-updates/s of a group), and a 500k-frame run's time at
    those rates."""
    if not (run_dir / "config.yaml").is_file():
        raise SystemExit(f"{run_dir}: no config.yaml, not a gentlerl run directory")
    cfg = yaml.safe_load((run_dir / "config.yaml").read_text())
    scalars = load_run(run_dir).scalars  # (frames, values) of each logged scalar
    if "train/wall_s" not in scalars:
        raise SystemExit(f"{run_dir}: no train/wall_s logged yet (stopped before the first log)")
    ups = np.stack(scalars.get("train/updates_per_s", (np.zeros(0), np.zeros(0))), -1)
    steps = np.stack(scalars["train/wall_s"], -1)
    random = steps[steps[:, 0] <= random_frames]
    learning = steps[steps[:, 0] > random_frames]
    random_fps = random[-1, 0] / random[-1, 1] if len(random) else float("nan")
    learn_fps = (
        (learning[-1, 0] - random[-1, 0]) / (learning[-1, 1] - random[-1, 1])
        if len(learning) and len(random)
        else float("nan")
    )
    projected = random_frames / random_fps + (PAPER_FRAMES - random_frames) / learn_fps
    return {
        "task": cfg["task"],
        "device": cfg["learner"]["device"],
        "graphs": bool(cfg["learner"]["cudagraphs"]),
        "workers": cfg["collector"]["num_workers"] if cfg["collector"]["kind"] == "multi" else 1,
        "frames": int(steps[-1, 0]),
        "wall_s": float(steps[-1, 1]),
        "random_phase_frames_per_s": random_fps,
        "learning_frames_per_s": learn_fps,
        "loop_updates_per_s_median": float(np.median(ups[:, 1])) if len(ups) else float("nan"),
        "seeds": seeds,
        "seed_updates_per_s": seeds * float(np.median(ups[:, 1])) if len(ups) else float("nan"),
        "projected_500k_min": projected / 60,
        "final_success": None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="fragile")
    parser.add_argument("--frames", type=int, default=30_000)
    parser.add_argument("--random-frames", type=int, default=10_000)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--graphs", action="store_true", help="learner.compile + cudagraphs")
    parser.add_argument("--replay-on-device", action="store_true", help="replay.device=learner")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--threads", type=int, default=1, help="torch threads of the learner")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", type=int, default=1, help="> 1: seeds 0..S-1 as a seed group")
    parser.add_argument("--run-dir", help="where the run writes (default: a temporary folder)")
    parser.add_argument("--from-logs", metavar="RUN_DIR", help="only read a run's logged rates")
    parser.add_argument("--json")
    args = parser.parse_args()
    if not 0 < args.random_frames < args.frames:
        parser.error(
            f"need 0 < --random-frames < --frames, got {args.random_frames}, {args.frames}"
        )
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    if args.seeds > 1 and args.seed != 0:
        parser.error(f"--seeds {args.seeds} trains seeds 0..{args.seeds - 1}: leave --seed out")
    if args.from_logs:
        row = rates(Path(args.from_logs), args.random_frames, args.seeds)
    elif args.run_dir:
        row = run(args, Path(args.run_dir))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            row = run(args, Path(tmp) / "run")
    print(json.dumps(row), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(row, indent=1))
    print(f"\nload {os.getloadavg()[0]:.1f}")
    print("| task | learner | seeds | workers | frames | wall s | frames/s random / learning "
          "| loop updates/s (x seeds) | 500k frames at these rates |")  # fmt: skip
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    learner = f"{row['device']}{' + compile + graphs' if row['graphs'] else ''}"
    print(
        f"| {row['task']} | {learner} | {row['seeds']} | {row['workers']} | {row['frames']:,} "
        f"| {row['wall_s']:.0f} "
        f"| {row['random_phase_frames_per_s']:,.0f} / {row['learning_frames_per_s']:,.0f} "
        f"| {row['loop_updates_per_s_median']:,.0f} ({row['seed_updates_per_s']:,.0f}) "
        f"| {row['projected_500k_min']:.1f} min |"
    )


if __name__ == "__main__":
    main()
