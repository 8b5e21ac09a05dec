"""Where the default recipe's time goes: ``train`` under cProfile, printed as a markdown table.

Rows: the calls the training loop makes (collection, reward transforms, buffers, model and learner
updates, evaluation, logging, checkpoints), then a few totals found anywhere in the profile
(MuJoCo physics, the TorchRL env step, tensordict's ``from_any``). Times are cProfile's (its
overhead inflates Python-heavy rows); the share of each row is what to read.

Run: ``python benchmarks/profile_recipe.py [--frames 20000] [key=value ...]`` (config overrides,
e.g. ``num_envs=4``); ``--out FILE`` keeps the raw profile for ``python -m pstats``.

``--update [--compile]``: instead, ``torch.profiler``'s table (ops by self time, per update) of
one full update at the recipe's sizes as ``learner_speed.py`` times it (``Learner.update`` +
the penalty ensemble's update), on one thread.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import re
import tempfile
import time

import torch
import yaml

from gentlerl.training import make_config, train

#: Functions whose callees are the loop's phases (callees of every one found, minus each other).
LOOP = tuple(
    rf"training/loop\.py:\d+\({name}\)"
    for name in (
        "run", "_collect", "_loop", "_rewarded", "_store", "_earn_updates", "update",
        "_log_training",
    )
)  # fmt: skip
#: Totals found anywhere: label -> (pattern, "tottime" or "cumtime").
TOTALS = {
    "MuJoCo physics (mj_step*, anywhere)": (r"<built-in method mujoco\._functions\.mj_step", 2),
    "TorchRL EnvBase.step (anywhere)": (r"torchrl/envs/common\.py:\d+\(step\)", 3),
    "tensordict from_any (anywhere)": (r"tensordict/base\.py:\d+\(from_any\)", 3),
}


def _label(func: tuple[str, int, str]) -> str:
    path, line, name = func
    where = path.split("site-packages/")[-1].split("src/")[-1]
    return f"`{name}` ({where}:{line})"


def breakdown(stats: pstats.Stats, min_share: float = 0.003) -> list[tuple[str, float]]:
    """``[(label, seconds)]``: the loop's callees by cumulative time, then :data:`TOTALS`."""
    table = stats.stats  # func -> (cc, nc, tottime, cumtime, callers)
    names = {f"{path}:{line}({name})": func for func in table for path, line, name in [func]}
    loops = {names[n] for pattern in LOOP for n in names if re.search(pattern, n)}
    callees = [
        (func, sum(c[3] for caller, c in callers.items() if caller in loops))
        for func, (*_, callers) in table.items()
        if func not in loops and loops & set(callers)
    ]
    rows = [(_label(f), t) for f, t in sorted(callees, key=lambda x: -x[1])]
    for label, (pattern, column) in TOTALS.items():
        total = sum(
            v[column] for n, v in ((n, table[f]) for n, f in names.items()) if re.search(pattern, n)
        )
        rows.append((label, total))
    return rows


def profile_update(compile: bool, updates: int = 50, rows: int = 25) -> None:
    """Print the ops of one full update (learner_speed's recipe scale) by self CPU time."""
    from learner_speed import make_full_update, make_scale  # the sibling benchmark script

    step = make_full_update(make_scale("recipe"), "cpu", compile=compile)
    for _ in range(20):
        step()
    with torch.profiler.profile(activities=[torch.profiler.ProfilerActivity.CPU]) as prof:
        for _ in range(updates):
            step()
    events = sorted(prof.key_averages(), key=lambda e: -e.self_cpu_time_total)
    total = sum(e.self_cpu_time_total for e in events)
    print(
        f"learner.compile={compile}: {total / updates / 1e3:.2f} ms of ops per update, load "
        f"average {os.getloadavg()[0]:.1f}\n\n| op | calls / update | us / update | share |"
    )
    print("| --- | ---: | ---: | ---: |")
    for e in events[:rows]:
        us = e.self_cpu_time_total / updates
        print(f"| `{e.key[:60]}` | {e.count / updates:g} | {us:.0f} | {us * updates / total:.1%} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20_000)
    parser.add_argument("--out", default=None, help="save the raw profile here")
    parser.add_argument("--update", action="store_true", help="profile one learner update")
    parser.add_argument("--compile", action="store_true", help="--update with learner.compile")
    parser.add_argument("overrides", nargs="*", help="config overrides group.field=value")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.update:
        return profile_update(args.compile)
    overrides: dict = {"collector": {"total_frames": args.frames}}
    overrides["logging"] = {"progress": False, "wandb_mode": "offline"}
    for name, value in (o.split("=", 1) for o in args.overrides):
        group, _, field = name.rpartition(".")
        (overrides.setdefault(group, {}) if group else overrides)[field] = yaml.safe_load(value)
    with tempfile.TemporaryDirectory() as run_dir:
        cfg = make_config(run_dir=run_dir, **overrides)
        profiler = cProfile.Profile()
        start = time.perf_counter()
        profiler.runcall(train, cfg)
        wall = time.perf_counter() - start
    if args.out:
        profiler.dump_stats(args.out)
    stats = pstats.Stats(profiler)
    total = stats.total_tt
    load = os.getloadavg()[0]
    print(
        f"{args.frames:,} frames, overrides {overrides or 'none'}: wall {wall:.0f} s under cProfile "
        f"({args.frames / wall:.0f} frames/s), load average {load:.1f} at the end\n"
    )
    print("| where | s | share |\n| --- | ---: | ---: |")
    for label, seconds in breakdown(stats):
        if seconds >= 0.003 * total:
            print(f"| {label} | {seconds:.1f} | {seconds / total:.1%} |")


if __name__ == "__main__":
    main()
