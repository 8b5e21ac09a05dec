"""Training throughput of the default recipe under collection settings, as a markdown table.

Each setting is a set of config overrides (``collector.num_envs=4 collector.overlap=true``); every setting trains the
default recipe for ``--frames`` frames (updates from ``--random-frames`` on, evaluations and
checkpoints as configured), in ``--rounds`` interleaved rounds so that all settings see the same
background load; the best round counts. Frames/s is over the whole run (collection, updates,
evaluation, logging, checkpoints).

Run: ``python benchmarks/train_speed.py "collector.num_envs=1" "" "collector.overlap=true"``
("" = the defaults); ``--eval-every-frames`` / ``--checkpoint-every-frames`` past ``--frames``
time training alone (``"collector.overlap=process"``: collection in a child process).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import torch
import yaml

from gentlerl.training import make_config, train


def _overrides(setting: str, frames: int, random_frames: int, logging: dict) -> dict:
    """``group.field=value`` items on top of the run length and quiet ``logging``."""
    overrides: dict = {
        "collector": {"total_frames": frames, "init_random_frames": random_frames},
        "logging": {"progress": False, "wandb_mode": "disabled", **logging},
    }
    for name, value in (item.split("=", 1) for item in setting.split()):
        group, _, key = name.rpartition(".")
        (overrides.setdefault(group, {}) if group else overrides)[key] = yaml.safe_load(value)
    return overrides


def run(setting: str, frames: int, random_frames: int, seed: int, logging: dict) -> float:
    """Seconds to train ``frames`` frames with ``setting`` (``logging`` overrides on top)."""
    with tempfile.TemporaryDirectory() as run_dir:
        overrides = _overrides(setting, frames, random_frames, logging)
        cfg = make_config(run_dir=run_dir, seed=seed, **overrides)
        start = time.perf_counter()
        train(cfg)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("settings", nargs="+", help='config overrides, "" for the defaults')
    parser.add_argument("--frames", type=int, default=8_000)
    parser.add_argument("--random-frames", type=int, default=2_000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-every-frames", type=int, help="default: the recipe's")
    parser.add_argument("--checkpoint-every-frames", type=int, help="default: the recipe's")
    args = parser.parse_args()
    logging = {
        name: value
        for name, value in (
            ("eval_every_frames", args.eval_every_frames),
            ("checkpoint_every_frames", args.checkpoint_every_frames),
        )
        if value is not None
    }
    torch.set_num_threads(1)
    best = dict.fromkeys(args.settings, float("inf"))
    loads = []
    for round_ in range(args.rounds):
        for setting in args.settings:
            seconds = run(setting, args.frames, args.random_frames, args.seed, logging)
            best[setting] = min(best[setting], seconds)
            loads.append(os.getloadavg()[0])
            print(f"round {round_}: {setting or 'defaults'} {seconds:.1f} s, load {loads[-1]:.1f}")
    base = best[args.settings[0]]
    print(
        f"{args.frames:,} frames ({args.random_frames:,} random), best of {args.rounds} rounds, "
        f"load average {min(loads):.1f}-{max(loads):.1f}\n"
    )
    print("| setting | wall s | frames/s | x first |\n| --- | ---: | ---: | ---: |")
    for setting, seconds in best.items():
        print(
            f"| {setting or 'defaults'} | {seconds:.0f} | {args.frames / seconds:.0f} "
            f"| {base / seconds:.2f} |"
        )


if __name__ == "__main__":
    main()
