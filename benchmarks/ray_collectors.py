"""Env frames/s of remote Ray collectors vs the in-process collector, and the learner's updates/s
while they collect; a projection of the paper-scale grid on 8 and 64 CPUs.

    python benchmarks/ray_collectors.py [--frames 2000] [--markdown]

Collection: the `touch` hand env with the cpu-scale exploration policy (actor 256-256 + Gaussian
noise), ``frames_per_batch=200``, timed after the first batch (actor start-up excluded, reported
apart). Ray collectors are the ones of ``collector=ray`` (synchronous, 1 CPU per worker) on a local
Ray. Learner: the full update of the loop (D4PG loss + the penalty / dynamics ensembles, variant
r+rf+rsp) on buffers filled by collection, at the cpu scale and the paper scale, alone and while 2
Ray workers collect on a background thread.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import threading
import time

import torch
from torchrl.collectors import Collector

from gentlerl.distributed.collector import make_ray_collector
from gentlerl.training import Lockstep, Trainer, make_config
from gentlerl.training.builders import AGENT_KEYS, default_env_factory
from gentlerl.training.config import TrainConfig

#: The paper-scale grid of recipes/grids/reproduce.sh: 57 runs of 500k env frames (utd 1).
GRID_RUNS, PAPER_FRAMES = 57, 500_000


def _collect_rate(collector, frames: int) -> tuple[float, float]:
    """(seconds to the first batch, frames/s after it)."""
    if hasattr(collector, "remote_collectors"):
        collector.update_policy_weights_()  # as the loop does before its first batch
    start, first, n = time.perf_counter(), None, 0
    for batch in collector:
        if first is None:
            first = time.perf_counter()
            continue
        n += batch.numel()
        if n >= frames:
            break
    rate = n / (time.perf_counter() - first)
    collector.shutdown()
    return first - start, rate


def _trainer(cfg: TrainConfig, fill_frames: int) -> Trainer:
    """A Trainer whose buffers hold ``fill_frames`` reward-transformed hand-env steps."""
    trainer = Trainer(cfg)
    collector = Collector(
        trainer.env_factory, None, frames_per_batch=200, total_frames=fill_frames,
        auto_register_policy_transforms=False,
    )  # fmt: skip
    rewards = [("next", k) for k in trainer.rewards.reward_keys]
    for batch in collector:
        batch = trainer.rewards.transform(batch)
        trainer.rewards.extend(batch)
        trainer.writer.extend(batch.select(*AGENT_KEYS, *rewards))
    collector.shutdown()
    return trainer


def _update_rate(trainer: Trainer, seconds: float = 10.0) -> float:
    """Full updates (every model, then the D4PG learner) per second."""
    loop = Lockstep([trainer])
    loop.update()  # warm-up
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        loop.update()
        n += 1
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2000, help="frames timed per collector")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    tmp = tempfile.mkdtemp()
    quiet = {"wandb_mode": "disabled", "progress": False}
    cfg = make_config(run_dir=f"{tmp}/cpu", logging=quiet)
    trainer = _trainer(cfg, 1000)
    env_factory, policy = default_env_factory(cfg), trainer.builder.make_policy(trainer.learner)
    total = args.frames + 400
    rows = {}
    inproc = Collector(env_factory, policy, frames_per_batch=200, total_frames=total,
                       auto_register_policy_transforms=False)  # fmt: skip
    rows["in-process Collector"] = _collect_rate(inproc, args.frames)
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    for workers in (1, 2):
        collector = make_ray_collector([env_factory] * workers, policy, frames_per_batch=200,
                                       total_frames=total, init_random_frames=0)  # fmt: skip
        rows[f"Ray, {workers} remote collector(s)"] = _collect_rate(collector, args.frames)
    updates = {"cpu scale, alone": _update_rate(trainer)}
    paper = _trainer(make_config("paper", run_dir=f"{tmp}/paper", logging=quiet), 1000)
    updates["paper scale, alone"] = _update_rate(paper)
    collector = make_ray_collector([env_factory] * 2, policy, frames_per_batch=200,
                                   total_frames=10**9, init_random_frames=0)  # fmt: skip
    stop, frames = threading.Event(), [0, 0.0]

    def pull() -> None:
        for batch in collector:
            if frames[1] == 0.0:
                frames[1] = time.perf_counter()
            else:
                frames[0] += batch.numel()
            if stop.is_set():
                break

    thread = threading.Thread(target=pull)
    thread.start()
    while frames[1] == 0.0:
        time.sleep(0.5)
    for name, t in (("cpu", trainer), ("paper", paper)):
        updates[f"{name} scale, 2 Ray workers collecting"] = _update_rate(t)
    both = frames[0] / (time.perf_counter() - frames[1])
    stop.set()
    thread.join()
    collector.shutdown()
    ray.shutdown()
    report(rows, updates, both, args.markdown)


def report(rows: dict, updates: dict, both: float, markdown: bool) -> None:
    load = os.getloadavg()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load "
          f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")  # fmt: skip
    print("| collector | start-up (s) | env frames/s |\n| --- | ---: | ---: |")
    for name, (startup, rate) in rows.items():
        print(f"| {name} | {startup:.1f} | {rate:.0f} |")
    print(f"| Ray, 2 remote collectors, learner training meanwhile | - | {both:.0f} |")
    print("\n| learner (model + D4PG update) | updates/s |\n| --- | ---: |")
    for name, rate in updates.items():
        print(f"| {name} | {rate:.1f} |")
    inproc, per_worker = rows["in-process Collector"][1], rows["Ray, 1 remote collector(s)"][1]
    ups = updates["paper scale, alone"]
    print(
        f"\nprojection, paper-scale grid ({GRID_RUNS} runs x {PAPER_FRAMES // 1000}k frames, utd 1)"
    )
    print(
        "| CPUs | collectors per run | CPUs per run | runs at once | frames/s per run "
        "| grid frames/s | wall clock (h) |\n| ---: | --- | ---: | ---: | ---: | ---: | ---: |"
    )
    for cpus in (8, 64):
        for workers in (0, 1, 2, 3):
            print("| " + " | ".join(projection(cpus, workers, inproc, per_worker, ups)) + " |")


def projection(cpus: int, workers: int, inproc: float, per_worker: float, ups: float) -> list[str]:
    """One grid layout's numbers, from the measured per-worker rates (dedicated cores assumed).

    ``workers`` 0: the run collects in-process (1 CPU); else ``workers`` Ray collectors + the
    learner (``1 + workers`` CPUs). Collection and updates alternate (synchronous collector), so a
    run's frames/s is ``1 / (1 / collection rate + utd / updates per s)`` with utd 1.
    """
    collect = inproc if workers == 0 else workers * per_worker
    rate = 1.0 / (1.0 / collect + 1.0 / ups)
    at_once = cpus // (1 + workers)
    waves = -(-GRID_RUNS // at_once)
    hours = waves * PAPER_FRAMES / rate / 3600
    kind = "in-process" if workers == 0 else f"{workers} Ray"
    return [str(cpus), kind, str(1 + workers), str(at_once), f"{rate:.0f}",
            f"{at_once * rate:.0f}", f"{hours:.1f}"]  # fmt: skip


if __name__ == "__main__":
    main()
