"""A run's state as a checkpoint holds it: what a resumed :class:`~gentlerl.training.loop.Trainer`
needs (networks, optimisers, rewards' models and multiplier, buffers, counters, RNG), and what a
policy file keeps (config, sizes, actor)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

from gentlerl.agent.learner import TrainingState
from gentlerl.training import resume
from gentlerl.training.checkpoint import (
    check_critic_supports,
    critic_supports,
    load_replay_buffer_state,
    replay_buffer_state,
)
from gentlerl.training.checkpoint_schema import check_trainer_state
from gentlerl.training.seeding import rng_state, set_rng_state

if TYPE_CHECKING:
    from gentlerl.training.seed_run import SeedRun


def policy_state(trainer: SeedRun) -> dict[str, Any]:
    """What :func:`~gentlerl.training.checkpoint.load_policy` reads: config, sizes, actor."""
    return {
        "config": trainer.cfg.to_dict(),
        "obs_dim": trainer.builder.obs_dim,
        "action_dim": trainer.builder.action_dim,
        "actor": trainer.policy.state_dict(),
    }


def trainer_state(trainer: SeedRun) -> dict[str, Any]:
    """Everything a resumed run needs; the replay buffers only with ``checkpoint_buffer``."""
    keep = trainer.cfg.logging.checkpoint_buffer
    buffer = trainer.rewards.buffer if keep else None
    return {
        **policy_state(trainer),
        "learner": dataclasses.asdict(trainer.learner.state_of(trainer.seat)),
        "supports": critic_supports(trainer.loss.value_network),
        "intrinsic": trainer.rewards.state_dict(),
        "rb": replay_buffer_state(trainer.rb) if keep else None,
        "nstep": trainer.writer.state_dict() if keep else None,
        "model_rb": replay_buffer_state(buffer) if buffer is not None else None,
        "beta_schedule": trainer.beta_schedule.state_dict() if trainer.beta_schedule else None,
        "counters": dict(trainer.counters),
        "wall_s": trainer.wall_s,
        "eval_history": list(trainer.eval_history),
        "best_eval": trainer.best_eval,
        "rng": rng_state(),
    }


def load_trainer_state(trainer: SeedRun, state: dict[str, Any]) -> None:
    """Restore :func:`trainer_state`'s ``state`` into ``trainer`` (its checks first: every entry
    against the trainer, :func:`~gentlerl.training.checkpoint_schema.check_trainer_state`)."""
    check_trainer_state(trainer, state, trainer.layout.checkpoint)
    check_critic_supports(state, trainer.loss.value_network, trainer.layout.checkpoint)
    trainer.learner.restore(TrainingState(**state["learner"]), trainer.seat)
    trainer.rewards.load_state_dict(state["intrinsic"])
    for key, weight in trainer.rewards.head_weights().items():  # the objective as it was saved
        trainer.loss.set_head_weight(key, weight)
    if state["rb"] is not None:  # saved with checkpoint_buffer=false: start empty, refill
        load_replay_buffer_state(trainer.rb, state["rb"], trainer.layout.checkpoint)
        trainer.writer.load_state_dict(state["nstep"])
    if trainer.rewards.buffer is not None and state["model_rb"] is not None:
        load_replay_buffer_state(
            trainer.rewards.buffer, state["model_rb"], trainer.layout.checkpoint
        )
    if trainer.beta_schedule is not None:
        trainer.beta_schedule.load_state_dict(state["beta_schedule"])
    trainer.counters = resume.checked_counters(state["counters"], trainer.layout.checkpoint)
    trainer.wall_s = float(state.get("wall_s", 0.0))  # absent in checkpoints before it
    trainer.eval_history = list(state["eval_history"])
    trainer.best_eval = state["best_eval"]
    set_rng_state(state["rng"])
