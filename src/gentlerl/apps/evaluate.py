"""Evaluate a saved policy: ``gentlerl evaluate POLICY --episodes N [--task T] [--seed S]``.

``POLICY`` is anything :func:`gentlerl.training.load_policy` reads (a run's ``checkpoint.pt`` or
``best_policy.pt``, or a shipped policy of ``gentlerl export``). The actor runs without exploration
noise in the env its run trained on (its ``env.kwargs``, so the same physics regime), or on
another task with ``--task`` or another physics regime with ``--regime`` (:data:`gentlerl.envs.hand.REGIMES`).
Prints the success rate, the broken rate and the median / p90 of the per-episode max impact (paper
eq. 1, N); ``--episodes-csv`` also writes one row per episode (the columns of a run's
``eval_episodes.csv``, ``frames`` = the frames the policy trained for), which ``gentlerl plot``
reads as the final policy's episodes (paper Fig. 5).
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import IO

import torch

from gentlerl.apps.outputs import check_output_file
from gentlerl.apps.parsing import add_renamed, command_parser
from gentlerl.envs import REGIMES, TASKS, make_env
from gentlerl.files import write_atomic
from gentlerl.training.evaluation import summarize


def evaluate_policy(
    path: str | os.PathLike,
    episodes: int,
    *,
    task: str | None = None,
    regime: str | None = None,
    seed: int = 0,
    episodes_csv: str | os.PathLike | None = None,
) -> dict[str, float]:
    """Load the policy at ``path`` and run ``episodes`` deterministic episodes (see module doc).

    ``task`` / ``regime``: ``None`` keeps the run's own. ``episodes_csv``: also write the
    episodes there (:func:`write_episodes`). Returns ``task`` and the :func:`summarize` numbers.
    """
    from gentlerl.training.builders import default_env_factory
    from gentlerl.training.checkpoint import (
        checked_policy_frames,
        load_checkpoint,
        policy_from_state,
    )
    from gentlerl.training.evaluation import (
        MAX_EPISODE_STEPS,
        check_episodes,
        check_policy_fits,
        evaluate,
        make_eval_env,
    )
    from gentlerl.training.logging import force_unit

    check_episodes(episodes)
    if task is not None and task not in TASKS:
        raise ValueError(f"unknown task {task!r}; expected one of {list(TASKS)}")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise ValueError(f"seed must be an integer in [0, 2**32), got {seed!r}")
    if episodes_csv is not None:
        check_output_file(episodes_csv, (".csv",))  # before the episodes, not after
    state = load_checkpoint(path)
    cfg, actor = policy_from_state(state, path)
    frames = checked_policy_frames(state, path)  # before the episodes: a NaN count refused
    env_kwargs = dict(cfg.env.kwargs)
    if regime is not None:
        env_kwargs["regime"] = regime
    if cfg.env.name is not None:  # an external env (env.name): the run's own, seeded here
        if task is not None or regime is not None:
            raise ValueError(f"--task / --regime apply to the hand, not to {cfg.env.name}")
        env_factory = partial(default_env_factory(cfg), seed=seed)
    else:
        env_factory = partial(make_env, task or cfg.task, **env_kwargs)
    env = make_eval_env(env_factory, seed, force_key=cfg.env.force)
    torch.manual_seed(seed)
    try:
        check_policy_fits(env, actor, str(path))
        # The env's own time limit (200 steps by default) ends every episode before this cap.
        _, per_episode = evaluate(env, actor, episodes, max_steps=MAX_EPISODE_STEPS)
    finally:
        env.close()
    if episodes_csv is not None:
        write_episodes(episodes_csv, frames, per_episode)
    task_name = task or cfg.env.name or cfg.task
    return {"task": task_name, **summarize(per_episode), "unit": force_unit(cfg.env.force_scale)}


def write_episodes(
    path: str | os.PathLike, frames: int | None, episodes: Sequence[dict[str, float]]
) -> Path:
    """One CSV row per episode with a run's ``eval_episodes.csv`` columns, written atomically;
    ``frames``: the frames the policy trained for (-1 if unknown)."""
    from gentlerl.training.logging import episode_table

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header, rows = episode_table(-1 if frames is None else frames, episodes)

    def write(f: IO) -> None:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)

    write_atomic(path, write, newline="")
    return path


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl evaluate") -> dict[str, float]:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument(
        "policy", help="a run's checkpoint.pt or best_policy.pt, or an exported policy file"
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes to run")
    parser.add_argument("--task", choices=TASKS, help="task; None: the one the policy trained on")
    parser.add_argument(
        "--regime", choices=list(REGIMES), help="the hand's physics regime; None: the policy's own"
    )
    add_renamed(parser, "--calibration", "--regime (the hand's physics regime)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the block placements")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--episodes-csv", help="also write one row per episode to this CSV")
    args = parser.parse_args(argv)
    result = evaluate_policy(
        args.policy,
        args.episodes,
        task=args.task,
        regime=args.regime,
        seed=args.seed,
        episodes_csv=args.episodes_csv,
    )
    if args.json:
        print(json.dumps({"policy": str(args.policy), **result}))
    else:
        rates = "".join(
            f"{k.removesuffix('_rate')} {result[k]:.2f}  "
            for k in ("success_rate", "broken_rate")
            if k in result
        )
        print(
            f"{args.policy} on {result['task']}, {result['episodes']} episodes (seed {args.seed}):\n"
            f"  {rates}max impact median {result['median_max_impact']:.2f} {result['unit']}, "
            f"p90 {result['p90_max_impact']:.2f} {result['unit']}, "
            f"return {result['mean_return']:.1f}"
        )
    return result
