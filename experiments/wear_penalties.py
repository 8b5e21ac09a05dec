"""Wear penalties on touch: success, impacts, forces and actuator effort of each variant.

    python experiments/wear_penalties.py [--frames 25000] [--seeds 0 1 2] [--regime easy]
                                        [--out runs/wear] [--no-train]

Trains every variant of ``--variants`` (default: the paper's ``r+rf+rsp`` and the same plus the
total-force penalty ``rF`` or the actuator-effort penalty ``rt``) on ``touch`` for each seed, one
run at a time, with the CPU reproduction's protocol (``--frames`` env frames, an evaluation of
``--eval-episodes`` every 5k frames). Finished runs (``DONE``) are reused. Then it rolls out the
final actor of each run for ``--episodes`` deterministic episodes on fresh seeds and prints one
markdown row per variant: final success, mean in-training eval success, and per episode the max
impact (eq. 1), the max total fingertip force and the mean summed actuator effort.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.envs import make_env
from gentlerl.files import read_checked
from gentlerl.training import load_policy, make_config, train
from gentlerl.transforms import ImpactPenalty

VARIANTS = ("r+rf+rsp", "r+rf+rsp+rF", "r+rf+rsp+rt")


def _train(variant: str, seed: int, args: argparse.Namespace) -> Path:
    run_dir = args.out / variant / f"seed{seed}"
    if not (run_dir / "DONE").exists():
        start = time.perf_counter()
        env_kwargs = {"regime": args.regime} if args.regime else {}
        cfg = make_config(
            task="touch",
            variant=variant,
            seed=seed,
            run_dir=str(run_dir),
            resume=(run_dir / "checkpoint.pt").exists(),
            env={"kwargs": env_kwargs},
            collector={"total_frames": args.frames},
            logging={
                "eval_every_frames": 5000,
                "eval_episodes": args.eval_episodes,
                "wandb_mode": "disabled",
                "progress": False,
            },
        )
        train(cfg)
        print(f"{variant} seed {seed}: {time.perf_counter() - start:.0f} s", flush=True)
    return run_dir


@torch.no_grad()
def _rollouts(run_dir: Path, episodes: int, seed: int) -> list[dict[str, float]]:
    cfg, actor = load_policy(run_dir / "checkpoint.pt")
    env = TransformedEnv(make_env(cfg.task, seed=seed, **cfg.env.kwargs), ImpactPenalty())
    rows = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            nxt = env.rollout(200, actor, break_when_any_done=True).get("next")
            rows.append(
                {
                    "success": float(nxt.get(keys.SUCCESS).any()),
                    "max_impact": float(nxt.get(keys.IMPACT).max()),
                    "max_force": float(nxt.get(keys.TOUCH).sum(-1).max()),
                    "effort": float(nxt.get(keys.ACTUATOR_FORCE).abs().sum(-1).mean()),
                }
            )
    env.close()
    return rows


def _eval_success(run_dir: Path) -> list[float]:
    """Eval success at each evaluation (the final one is logged twice: kept once)."""
    path = run_dir / "logs" / "scalars" / "eval" / "success_rate.csv"
    rows = [line.split(",") for line in read_checked(path).splitlines() if line[:1].isdigit()]
    return list({frames: float(value) for frames, value in rows}.values())


def _row(variant: str, runs: list[Path], episodes: list[list[dict[str, float]]]) -> str:
    flat = [e for per_run in episodes for e in per_run]
    final = [statistics.mean(e["success"] for e in per_run) for per_run in episodes]
    during = [statistics.mean(_eval_success(r)) for r in runs]

    def med_p90(name: str) -> str:
        values = np.array([e[name] for e in flat])
        return f"{np.median(values):.2f} / {np.percentile(values, 90):.2f}"

    seeds = ", ".join(r.name.removeprefix("seed") for r in runs)
    return (
        f"| `{variant}` | {seeds} | {' / '.join(f'{s:.1f}' for s in final)} | "
        f"{statistics.mean(during):.2f} | {med_p90('max_impact')} | {med_p90('max_force')} | "
        f"{statistics.mean(e['effort'] for e in flat):.3f} |"
    )


def _table(results: dict[str, tuple[list[Path], list[list[dict[str, float]]]]]) -> str:
    header = (
        "| variant | seeds | final success per seed | mean eval success during training | "
        "max impact (N) median / p90 | max total force (N) median / p90 | "
        "mean actuator effort sum_j abs(tau_j) (N m) |\n"
        "| --- | --- | --- | ---: | ---: | ---: | ---: |"
    )
    return "\n".join([header, *(_row(v, *r) for v, r in results.items() if r[0])])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--frames", type=int, default=25_000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--episodes", type=int, default=10, help="final rollouts per run")
    parser.add_argument("--out", type=Path, default=Path("runs/wear"))
    parser.add_argument("--regime", help="the hand's physics regime (default: the env's default)")
    parser.add_argument(
        "--no-train", action="store_true", help="only evaluate the runs that are finished"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    if not args.no_train:
        # Seed-major order: an interrupted comparison still has every variant on the first seeds.
        for seed in args.seeds:
            for variant in args.variants:
                _train(variant, seed, args)
    results = {}
    for variant in args.variants:
        done = [s for s in args.seeds if (args.out / variant / f"seed{s}" / "DONE").exists()]
        run_dirs = [args.out / variant / f"seed{s}" for s in done]
        # Evaluation seeds differ from training seeds: 1000 + training seed.
        episodes = [
            _rollouts(r, args.episodes, 1000 + s) for r, s in zip(run_dirs, done, strict=True)
        ]
        results[variant] = (run_dirs, episodes)
    print(
        f"\n{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.1f}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(_table(results))


if __name__ == "__main__":
    main()
