"""Collection frames/s over worker processes: TorchRL's ``MultiSyncCollector`` as training builds it.

    python benchmarks/collect_scale.py [--workers 1 4 16] [--hands 4] [--batches 20]
        [--task touch] [--json F]

Each row builds the run's collector with gentlerl's own builder
(:func:`gentlerl.training.builders.make_collector`, ``collector.kind=multi`` with ``num_workers``
processes, or ``single`` for one worker) around the paper-size actor with Gaussian exploration
noise on the CPU, ``--hands`` hands stepped together per worker (``BatchedHandEnv``, one physics
thread each), ``frames_per_batch`` = 50 x hands x workers (each worker returns 50 steps of its
hands per batch). After two warm-up batches it times ``--batches`` batches: frames/s, and the
scaling efficiency against ``workers x`` the one-worker rate. The goal on a 16-core machine:
>= 10,000 frames/s with 16 workers, >= 0.6 x linear.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import torch

from gentlerl.config import CollectorConfig
from gentlerl.envs import make_env
from gentlerl.envs.hand import FLAT_SIZE, N_ACTUATORS
from gentlerl.models import make_actor, make_exploration_policy
from gentlerl.training.builders import make_collector

STEPS_PER_WORKER = 50


def _hand_env(task: str, **kwargs):
    return make_env(task, **kwargs)


def frames_per_s(task: str, workers: int, hands: int, batches: int) -> dict:
    frames = STEPS_PER_WORKER * hands * workers
    cfg = CollectorConfig(
        kind="multi" if workers > 1 else "single",
        num_workers=max(workers, 1),
        num_envs=hands,
        env_threads=1,
        frames_per_batch=frames,
    )
    torch.manual_seed(0)
    policy = make_exploration_policy(
        make_actor(FLAT_SIZE, N_ACTUATORS), 0.3, action_dim=N_ACTUATORS
    )
    factory = _Factory(task)
    start = time.perf_counter()
    collector = make_collector(cfg, factory, policy, -1, 0, seed=0)
    try:
        it = iter(collector)
        for _ in range(2):
            next(it)
        setup_s = time.perf_counter() - start
        t0 = time.perf_counter()
        for _ in range(batches):
            next(it)
        rate = batches * frames / (time.perf_counter() - t0)
    finally:
        collector.shutdown()
    return {"workers": workers, "hands": hands, "frames_per_s": rate, "setup_s": setup_s}


class _Factory:
    """``make_env(task, ...)`` with a ``num_envs`` parameter the builder can see (picklable)."""

    def __init__(self, task: str) -> None:
        self.task = task

    def __call__(self, num_envs: int = 1, num_threads: int | None = None):
        return _hand_env(self.task, num_envs=num_envs, num_threads=num_threads)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--hands", type=int, default=4)
    parser.add_argument("--batches", type=int, default=20)
    parser.add_argument("--task", default="touch")
    parser.add_argument("--json")
    args = parser.parse_args()
    if min(args.workers) < 1 or args.hands < 1 or args.batches < 1:
        parser.error("--workers, --hands and --batches must be >= 1")
    torch.set_num_threads(1)
    print(
        f"collect_scale: task {args.task}, {args.hands} hands per worker, {os.cpu_count()} CPUs, "
        f"load {os.getloadavg()[0]:.1f}",
        flush=True,
    )
    rows = []
    for workers in args.workers:
        rows.append(frames_per_s(args.task, workers, args.hands, args.batches))
        print(json.dumps(rows[-1]), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    one = next((r["frames_per_s"] for r in rows if r["workers"] == 1), None)
    print("\n| workers | hands each | frames/s | x linear from 1 worker | setup s |")
    print("| ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        eff = f"{r['frames_per_s'] / (one * r['workers']):.2f}" if one else "-"
        print(
            f"| {r['workers']} | {r['hands']} | {r['frames_per_s']:,.0f} | {eff} "
            f"| {r['setup_s']:.1f} |"
        )


if __name__ == "__main__":
    main()
