"""A run's evaluations during training: the actor's noise-free episodes logged (with each critic
head's prediction against what they returned), kept in the run's history, the best actor saved,
and the penalty's multiplier steered on episodes; for each seed's run
(:class:`~gentlerl.training.seed_run.SeedRun`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gentlerl.training import run_state
from gentlerl.training.checkpoint import save_checkpoint
from gentlerl.training.critic_calibration import evaluation_scalars
from gentlerl.training.evaluation import evaluate, rank, rollout_episodes, summarize_episodes
from gentlerl.training.logging import RunLogger

if TYPE_CHECKING:
    from torchrl.envs import EnvBase

    from gentlerl.training.seed_run import SeedRun


def final_evaluation(trainer: SeedRun, logger: RunLogger, eval_env: EnvBase) -> dict[str, float]:
    """The last batch's evaluation where it was at the final frame, else a new one."""
    last = trainer.eval_history[-1] if trainer.eval_history else {"frames": -1}
    if last["frames"] == trainer.counters["frames"]:
        return {k: v for k, v in last.items() if k != "frames"}
    return evaluate_run(trainer, logger, eval_env)


def evaluate_run(trainer: SeedRun, logger: RunLogger, eval_env: EnvBase) -> dict[str, float]:
    """``logging.eval_episodes`` noise-free episodes of the acting actor, logged and ranked."""
    episodes = trainer.cfg.logging.eval_episodes
    policy, horizon = trainer.policy, trainer.builder.horizon
    rollouts = rollout_episodes(eval_env, policy, episodes, horizon)
    summary, per_episode = summarize_episodes(rollouts, trainer.cfg.gentleness.tolerance)
    frames = trainer.counters["frames"]
    logger.log({f"eval/{k}": v for k, v in summary.items()}, frames)
    # The same episodes: each critic head's predicted Q against its realised return.
    loss, gamma = trainer.loss, trainer.cfg.learner.gamma
    logger.log(evaluation_scalars(loss, trainer.rewards.transform, rollouts, gamma), frames)
    logger.log_eval_episodes(frames, per_episode)
    trainer.eval_history.append({"frames": frames, **summary})
    keep_best(trainer, {"frames": frames, **summary})
    return summary


def keep_best(trainer: SeedRun, result: dict[str, float]) -> None:
    """Save the actor to ``best_policy.pt`` when this evaluation beats every earlier one
    (:func:`~gentlerl.training.evaluation.rank`): DDPG can lose a solved task later on."""
    if trainer.best_eval is not None and rank(result) <= rank(trainer.best_eval):
        return
    trainer.best_eval = dict(result)
    state = {**run_state.policy_state(trainer), "eval": trainer.best_eval}
    save_checkpoint(trainer.layout.best_policy, state)


def steer(
    trainer: SeedRun, episodes: list[dict[str, float]], logger: RunLogger, eval_env: EnvBase
) -> None:
    """The penalty head's weight after the finished ``episodes`` (``gentleness.multiplier``),
    or with ``multiplier_episodes`` after that many noise-free episodes at each PID step."""
    if trainer.rewards.lagrangian is not None:
        return _steer_lagrangian(trainer, episodes, logger)
    multiplier, frames = trainer.rewards.multiplier, trainer.counters["frames"]
    if multiplier is None or not trainer.learning():
        return  # the policy's episodes only: not those of the first random actions
    if not episodes and multiplier.period is None:
        return  # stepped per episode
    if n := trainer.cfg.gentleness.multiplier_episodes:  # the deployed policy's cost
        policy, horizon = trainer.policy, trainer.builder.horizon
        episodes = evaluate(eval_env, policy, n, horizon)[1] if multiplier.due(frames) else []
    multiplier.observe([e["max_impact"] for e in episodes], frames=frames)
    _apply_head_weights(trainer)
    logger.log({f"train/{k}": v for k, v in multiplier.scalars().items()}, frames)


def _steer_lagrangian(
    trainer: SeedRun, episodes: list[dict[str, float]], logger: RunLogger
) -> None:
    """Every head's weight after the finished ``episodes``' costs (``multiplier=lagrangian``);
    the episodes of the first random actions count too (the warm-up keeps the multiplier)."""
    lagrangian, frames = trainer.rewards.lagrangian, trainer.counters["frames"]
    if not episodes:
        return
    lagrangian.observe([e["cost"] for e in episodes], frames)
    _apply_head_weights(trainer)
    logger.log({f"train/{k}": v for k, v in lagrangian.scalars().items()}, frames)


def _apply_head_weights(trainer: SeedRun) -> None:
    """The actor's weights on the heads the run's multiplier steers, as it stands now."""
    for key, weight in trainer.rewards.head_weights().items():
        trainer.loss.set_head_weight(key, weight)
