"""Critic calibration of a run: ``gentlerl calibration RUN_DIR_OR_CHECKPOINT [--episodes N]``.

Loads a run's full ``checkpoint.pt`` (actor, critics, reward models and whether the curiosity
rewards are on), rolls its actor out on the run's task, deterministically and with the run's
exploration noise (``collector.sigma``), and prints per critic head the mean predicted Q against
the mean realised discounted return (:mod:`gentlerl.training.critic_calibration`), over every
step and at episode start.

Columns: ``predicted`` and ``realised`` means, ``bias`` = predicted - realised, ``mae`` the mean
absolute error per step, ``rel_err`` = |bias| / max(|realised|, 0.1), ``outside`` the fraction of
realised returns outside the head's support, ``boot`` the part of the realised mean that is the
critic's own bootstrap (truncation; termination too for non-episodic heads).

With penalty surprise, a last line per mode says where its bonus on contact steps comes from
(:func:`~gentlerl.training.critic_calibration.penalty_surprise_sources`): the curiosity
a' s nll and the refund -a' r^f, the NLL's spread and error terms, the penalty model's mean squared
z-score and its aleatoric / epistemic variance.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch
from torchrl.envs.utils import ExplorationType

from gentlerl.config.layout import RunLayout
from gentlerl.config.limits import MAX_HANDS
from gentlerl.files import write_atomic

if TYPE_CHECKING:
    from gentlerl.agent import Learner
    from gentlerl.rewards import IntrinsicRewards
    from gentlerl.training.config import TrainConfig

#: Rollout modes: the deterministic actor, and the actor with its training noise.
MODES = {"deterministic": ExplorationType.DETERMINISTIC, "noisy": ExplorationType.RANDOM}


def _checkpoint_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    return RunLayout(path).checkpoint if path.is_dir() else path


def fields_not_saved(saved_config: dict[str, Any]) -> list[str]:
    """The config fields of this gentlerl that a checkpoint's ``saved_config`` lacks: they get
    today's defaults when it is loaded, which may build other critics than the run trained (the
    critics' supports come from the config and are not saved with their weights)."""
    from gentlerl.training.config import iter_fields
    from gentlerl.training.migration import group_flat_config

    grouped = group_flat_config(saved_config)
    saved = {f"{g}.{name}" for g, v in grouped.items() if isinstance(v, dict) for name in v}
    saved |= {name for name, v in grouped.items() if not isinstance(v, dict)}
    return sorted({name for name, _ in iter_fields()} - saved)


def load_agent(
    path: str | os.PathLike,
) -> tuple[TrainConfig, Learner, IntrinsicRewards, dict[str, Any]]:
    """``(config, learner, intrinsic rewards, info)`` restored from a run's directory or its
    ``checkpoint.pt``; a ``ValueError`` (one line) for anything else. ``info``: ``frames``
    trained, ``not_saved`` (:func:`fields_not_saved`)."""
    from gentlerl.agent.builder import AgentBuilder
    from gentlerl.training.builders import default_env_factory
    from gentlerl.training.checkpoint import (
        POLICY_KEYS,
        check_critic_supports,
        checked_policy_frames,
        load_checkpoint,
        policy_from_state,
    )

    ckpt = _checkpoint_path(path)
    try:
        state = load_checkpoint(ckpt)
    except FileNotFoundError as err:
        raise ValueError(f"{err}: pass a run directory or its checkpoint.pt") from None
    missing = [k for k in POLICY_KEYS if k not in state]
    if missing:
        raise ValueError(f"{ckpt} is not a gentlerl checkpoint: it lacks {missing}")
    if "learner" not in state or "intrinsic" not in state:
        raise ValueError(
            f"{ckpt} holds an actor only (a best_policy.pt or an exported policy): the critics "
            "are in the run's checkpoint.pt"
        )
    cfg, _ = policy_from_state(state, ckpt)  # its config checked first: sizes within bounds
    env = None
    try:
        env = default_env_factory(cfg)()  # the run's own env (the hand, or an external one)
        builder = AgentBuilder(cfg, env)
        learner, rewards = builder.make_learner(), builder.rewards
        check_critic_supports(state, learner.loss.value_network, ckpt)
        learner.loss.load_state_dict(state["learner"]["networks"])
        rewards.load_state_dict(state["intrinsic"])
    except (RuntimeError, KeyError, ValueError, TypeError) as err:
        reason = (str(err).strip().splitlines() or [type(err).__name__])[0][:160]
        raise ValueError(f"{ckpt} does not match this gentlerl's agent ({reason})") from None
    finally:
        if env is not None:
            env.close()
    info = {
        "frames": checked_policy_frames(state, ckpt),
        "not_saved": fields_not_saved(state["config"]),
    }
    return cfg, learner, rewards, info


def critic_calibration(
    path: str | os.PathLike, episodes: int = 10, seed: int = 0
) -> dict[str, Any]:
    """Calibration of every critic head of the run at ``path``, per rollout mode (:data:`MODES`):
    ``{"checkpoint", "task", "variant", "frames", "gamma", "sigma", "intrinsic_on", "episodes",
    "seed", "supports": {head: [v_min, v_max]}, "not_saved": [config fields], "modes": {mode:
    {head: {"all" | "start": stats}}}, "surprise_kind"}`` (see
    :func:`~gentlerl.training.critic_calibration.measure_calibration`), and for a variant with
    penalty surprise ``"penalty_surprise_sources": {mode: stats}``
    (:func:`~gentlerl.training.critic_calibration.penalty_surprise_sources`).

    Both modes start from the same block placements (the env is seeded with ``seed``).
    """
    from gentlerl.envs import make_env
    from gentlerl.models import make_exploration_policy
    from gentlerl.training.builders import default_env_factory
    from gentlerl.training.critic_calibration import measure_calibration, penalty_surprise_sources
    from gentlerl.training.evaluation import make_eval_env, rollout_episodes

    if isinstance(episodes, bool) or not (isinstance(episodes, int) and 1 <= episodes <= MAX_HANDS):
        raise ValueError(
            f"episodes must be an integer in [1, {MAX_HANDS}] (one hand each, stepped together "
            f"as logging.eval_episodes are), got {episodes!r}"
        )
    cfg, learner, rewards, info = load_agent(path)
    actor = learner.actor
    policies = {
        "deterministic": actor,
        "noisy": make_exploration_policy(actor, cfg.collector.sigma),
    }
    if cfg.env.name is not None:  # an external env: the run's own (seeded by make_eval_env)
        env_factory = default_env_factory(cfg)
    else:
        env_factory = partial(make_env, cfg.task, **cfg.env.kwargs)
    env = make_eval_env(env_factory, seed, episodes, cfg.env.force)
    report = _report_head(path, cfg, learner, rewards, info) | {"episodes": episodes, "seed": seed}
    try:
        for mode, exploration in MODES.items():
            env.set_seed(seed)
            torch.manual_seed(seed)
            # The env's own time limit ends every episode before this cap.
            eps = rollout_episodes(env, policies[mode], episodes, 100_000, exploration)
            calib = measure_calibration(learner.loss, rewards.transform, eps, cfg.learner.gamma)
            report["modes"][mode] = calib
            sources = penalty_surprise_sources(rewards.transform, eps)
            if sources is not None:
                report.setdefault("penalty_surprise_sources", {})[mode] = sources
    finally:
        env.close()
    return report


def _report_head(
    path: str | os.PathLike,
    cfg: TrainConfig,
    learner: Learner,
    rewards: IntrinsicRewards,
    info: dict,
) -> dict[str, Any]:
    """What the report says of the run before its rollouts: where, what, and each head's support."""
    critic = learner.loss.value_network.module
    heads = [str(k) for k in learner.loss.reward_keys]
    bounds = zip(critic.v_min, critic.v_max, strict=True)
    return {
        "checkpoint": str(_checkpoint_path(path)),
        "task": cfg.task,
        "variant": cfg.variant,
        "frames": info["frames"],
        "gamma": cfg.learner.gamma,
        "sigma": cfg.collector.sigma,
        "intrinsic_on": rewards.intrinsic_on,
        "surprise_kind": cfg.gentleness.surprise_kind,
        "supports": {h: [lo, hi] for h, (lo, hi) in zip(heads, bounds, strict=True)},
        "not_saved": info["not_saved"],
        "modes": {},
    }


def format_table(report: dict[str, Any]) -> str:
    """A text table: one row per head, mode and where (every step / episode start)."""
    lines = [
        f"{report['checkpoint']}: {report['task']} {report['variant']}, {report['frames']} "
        f"frames, gamma {report['gamma']}, sigma {report['sigma']}, intrinsic "
        f"{'on' if report['intrinsic_on'] else 'off'}; {report['episodes']} episodes per mode "
        f"(seed {report['seed']})",
        "supports: "
        + ", ".join(f"{h} [{lo:g}, {hi:g}]" for h, (lo, hi) in report["supports"].items()),
        f"{'head':<18} {'mode':<13} {'where':<5} {'predicted':>9} {'realised':>9} {'bias':>9} "
        f"{'mae':>8} {'rel_err':>8} {'outside':>7} {'boot':>8}",
    ]
    for mode, heads in report["modes"].items():
        for head, where in heads.items():
            for at, s in where.items():
                lines.append(
                    f"{head:<18} {mode:<13} {at:<5} {s['predicted']:>9.3f} {s['realised']:>9.3f} "
                    f"{s['bias']:>+9.3f} {s['mae']:>8.3f} {s['rel_error']:>8.2f} "
                    f"{s['outside_support']:>7.2f} {s['bootstrap']:>8.3f}"
                )
    for mode, x in report.get("penalty_surprise_sources", {}).items():
        lines.append(_sources_line(mode, x, report))
    if report["not_saved"]:
        lines.insert(
            1,
            f"warning: the checkpoint predates config fields {report['not_saved']}; their "
            "defaults are assumed, so the critics may be read on other supports than they "
            "trained on",
        )
    return "\n".join(lines)


def _sources_line(mode: str, x: dict[str, Any], report: dict[str, Any]) -> str:
    """One line of :func:`format_table`: where the penalty surprise of contact steps comes from
    (the curiosity reads the NLL, or the ensemble's information gain I)."""
    reads = "I" if report.get("surprise_kind") == "information_gain" else "nll"
    head = f"penalty surprise, {mode}: {x['contact_steps']} contact steps of {x['steps']}"
    if not x["contact_steps"]:
        return f"{head}; no contact, nothing to decompose"
    sd = "n/a" if x["penalty_std"] is None else f"{x['penalty_std']:.3f}"
    return (
        f"{head}; r^sp {x['r_sp']:.3f} per contact step = curiosity a's*{reads} "
        f"{x['curiosity']:.3f} + refund -a'r^f {x['refund']:.3f}"
        f"{'' if report['intrinsic_on'] else ' (intrinsic rewards off: 0)'}; nll {x['nll']:.3f} = spread "
        f"{x['spread']:.3f} + error {x['error']:.3f} (mean z^2 {x['z2']:.2f}; over all steps "
        f"{x['z2_all_steps']:.2f}); model variance aleatoric {x['aleatoric']:.3f}, epistemic "
        f"{x['epistemic']:.3f}; r^f {x['penalty']:.3f} (sd {sd})"
    )


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl calibration") -> dict[str, Any]:
    from gentlerl.apps.parsing import command_parser

    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("run", help="a run directory or its checkpoint.pt (not an actor-only file)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per rollout mode")
    parser.add_argument("--seed", type=int, default=0, help="block placements and noise")
    parser.add_argument("--json", metavar="PATH", help="also write the report as JSON there")
    args = parser.parse_args(argv)
    from gentlerl.apps.outputs import check_output_file
    from gentlerl.training.checkpoint import CheckpointError

    try:
        if args.json is not None:  # before the rollouts, not after
            check_output_file(args.json, (".json",))
    except (ValueError, OSError) as err:
        raise SystemExit(f"{prog}: error: --json {err}") from None
    try:
        report = critic_calibration(args.run, args.episodes, args.seed)
    except (ValueError, CheckpointError) as err:
        raise SystemExit(f"{prog}: error: {str(err).splitlines()[0]}") from None
    print(format_table(report))
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, json.dumps(report, indent=1))
    return report
