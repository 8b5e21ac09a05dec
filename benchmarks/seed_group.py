"""A seed group against its seeds run one by one: wall clock and final numbers.

    python benchmarks/seed_group.py [--seeds 0 1 2] [--episodes 20] [--out DIR] [field=value ...]

Trains the seeds as one :class:`~gentlerl.training.seed_group.SeedGroup` (one process, the
models' and learners' updates one batched step), then each seed alone (``gentlerl train``'s
:func:`~gentlerl.training.train`), with the same settings (default: the touch task,
``r+rf+rsp``, 30k frames with 5k random and a 1k-update reward delay, as the Method III grid);
then evaluates every final actor on ``--episodes`` noise-free episodes (seed 0, as ``gentlerl
evaluate``). Prints each run's wall clock, each seed's final success and median max impact in
the group and alone, and the verdict of the rule in benchmarks/RESULTS.md ("a seed group").
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import yaml

from gentlerl.training import evaluate_actor, load_policy, make_config, train, train_seeds
from gentlerl.training.builders import default_env_factory

BUDGET = {
    "task": "touch",
    "variant": "r+rf+rsp",
    "num_threads": 1,
    "collector": {"total_frames": 30_000, "init_random_frames": 5_000, "num_envs": 1},
    "gentleness": {"reward_delay": 1_000},
    "logging": {
        "eval_every_frames": 5_000, "eval_episodes": 5, "checkpoint_buffer": False,
        "progress": False, "wandb_mode": "disabled",
    },
}  # fmt: skip


def _config(run_dir: Path, seed: int, overrides: list[str]):
    values = {k: dict(v) if isinstance(v, dict) else v for k, v in BUDGET.items()}
    for item in overrides:
        name, _, value = item.partition("=")
        group, _, key = name.rpartition(".")
        (values.setdefault(group, {}) if group else values)[key] = yaml.safe_load(value)
    return make_config(run_dir=str(run_dir), seed=seed, **values)


def final_numbers(run_dir: Path, episodes: int) -> dict[str, float]:
    """The run's last actor on ``episodes`` noise-free episodes (seed 0)."""
    cfg, actor = load_policy(run_dir / "checkpoint.pt")
    summary = evaluate_actor(default_env_factory(cfg), actor, episodes, seed=0)
    return {"success": summary["success_rate"], "impact": summary["median_max_impact"]}


def verdict(group: list[dict], alone: list[dict]) -> str:
    """The rule written before the first measurement (benchmarks/RESULTS.md)."""
    success = statistics.mean(r["success"] for r in group) - statistics.mean(
        r["success"] for r in alone
    )
    impacts = [r["impact"] for r in alone]
    allowed = max(0.5, max(impacts) - min(impacts))
    impact = statistics.median(r["impact"] for r in group) - statistics.median(impacts)
    holds = abs(success) <= 0.15 and abs(impact) <= allowed
    numbers = f"success {success:+.2f}, median max impact {impact:+.2f} N (allowed {allowed:.2f})"
    return f"{'learns as its seeds alone do' if holds else 'does not'}: {numbers}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--out", default="runs/seed_group")
    parser.add_argument("overrides", nargs="*", help="field=value on top of the budget")
    args = parser.parse_args()
    if len(set(args.seeds)) != len(args.seeds) or len(args.seeds) < 2:
        parser.error(f"--seeds needs two or more different seeds, got {args.seeds}")
    out = Path(args.out)
    if out.exists():
        parser.error(f"--out {out} exists: choose a new folder")
    group_cfgs = [_config(out / "group" / f"seed{s}", s, args.overrides) for s in args.seeds]
    start = time.perf_counter()
    train_seeds(group_cfgs)
    walls = {"group": time.perf_counter() - start}
    for s in args.seeds:
        start = time.perf_counter()
        train(_config(out / "alone" / f"seed{s}", s, args.overrides))
        walls[f"seed {s} alone"] = time.perf_counter() - start
    group = [final_numbers(out / "group" / f"seed{s}", args.episodes) for s in args.seeds]
    alone = [final_numbers(out / "alone" / f"seed{s}", args.episodes) for s in args.seeds]
    print(f"\nload {os.getloadavg()[0]:.1f}; wall clock (s): " + ", ".join(
        f"{k} {v:.0f}" for k, v in walls.items()
    ))  # fmt: skip
    print("\n| seed | group: success, median max impact (N) | alone |")
    print("| ---: | --- | --- |")
    for s, g, a in zip(args.seeds, group, alone, strict=True):
        print(
            f"| {s} | {g['success']:.2f}, {g['impact']:.2f} | {a['success']:.2f}, {a['impact']:.2f} |"
        )
    print(f"\n{verdict(group, alone)}")


if __name__ == "__main__":
    main()
