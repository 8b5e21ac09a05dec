"""The one training loop shared by every recipe: a thin runner over the agent's builder.

collect -> reward transforms -> buffers -> (model updates -> schedule) -> D4PG update -> log ->
evaluate -> checkpoint. The models learn from 1-step transitions (:class:`IntrinsicRewards`), the
learner from n-step ones (the prioritised buffer, written through an ``NStepWriter``). Updates
start after ``init_random_frames``; each frame then earns ``utd_ratio`` updates.
"""

from __future__ import annotations

import dataclasses
import time
from collections import defaultdict, deque
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from torchrl import timeit
from tqdm.auto import tqdm

from gentlerl.agent.builder import AgentBuilder
from gentlerl.agent.learner import TrainingState
from gentlerl.training import guards
from gentlerl.training.builders import (
    AGENT_KEYS,
    EnvFactory,
    check_env_keys,
    default_env_factory,
    make_collector,
    make_eval_env,
)
from gentlerl.training.checkpoint import (
    check_critic_supports,
    critic_supports,
    load_replay_buffer_state,
    remove_stale_temp_files,
    replay_buffer_state,
    save_checkpoint,
)
from gentlerl.training.config import TrainConfig, validate
from gentlerl.training.critic_calibration import calibration_scalars, measure_calibration
from gentlerl.training.evaluation import rank, rollout_episodes, summarize_episodes
from gentlerl.training.logging import EPISODE_KEYS, EpisodeStats, RunLogger, progress_postfix
from gentlerl.training.run_lock import RunLock
from gentlerl.training.seeding import rng_state, seed_everything, set_rng_state

CHECKPOINT = "checkpoint.pt"
#: The actor of the best evaluation so far (see :meth:`Trainer._keep_best`); ``load_policy`` reads it.
BEST_POLICY = "best_policy.pt"
DONE_MARKER = "DONE"


class Trainer:
    """Holds a run's state; :meth:`run` executes (or resumes) it. See :func:`train`."""

    def __init__(self, cfg: TrainConfig, env_factory: EnvFactory | None = None) -> None:
        validate(cfg)
        self.cfg = cfg
        self.run_dir = Path(cfg.run_dir)
        # Before anything is written: a refused resume leaves no trace in run_dir.
        self.ckpt = self.run_dir / CHECKPOINT
        self.resume_state = guards.load_resume_state(cfg, self.ckpt)
        torch.set_num_threads(cfg.num_threads)
        seed_everything(cfg.seed)
        if cfg.collector.kind == "ray":  # Ray installed, cluster reachable: before writing
            from gentlerl.distributed.cluster import join_cluster

            join_cluster(cfg.collector.ray_address)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.env_factory = env_factory or default_env_factory(cfg)
        probe = self.env_factory()
        self.builder = AgentBuilder(cfg, probe)
        self.max_steps = self.builder.horizon
        self.rewards = self.builder.make_intrinsic_rewards()
        check_env_keys(probe, self.rewards)
        probe.close()
        self.learner = self.builder.make_learner()
        col = cfg.collector
        updates = int(cfg.learner.utd_ratio * max(col.total_frames - col.init_random_frames, 0))
        self.writer, self.rb, self.beta_schedule = self.builder.make_replay(
            updates, self.rewards.window_keys
        )
        self.counters = {"frames": 0, "updates": 0, "update_credit": 0.0}
        self.eval_history: list[dict[str, float]] = []
        self.best_eval: dict[str, float] | None = None

    # -- the loop ------------------------------------------------------------------------
    def run(self) -> dict[str, float]:
        cfg = self.cfg
        remove_stale_temp_files(self.run_dir)
        if self.resume_state is not None:
            state, self.resume_state = self.resume_state, None
            done = guards.finished_summary(state, self.run_dir / DONE_MARKER, cfg)
            if done is not None:
                return done
            self.load_state_dict(state)
            guards.record_config_changes(self.run_dir, state, cfg.to_dict())
        config = guards.plain(cfg.to_dict())
        (self.run_dir / "config.yaml").write_text(yaml.safe_dump(config))
        log = cfg.logging
        logger = RunLogger(self.run_dir, config, log.wandb_mode, log.wandb_project, log.logger)
        logger.truncate_after(self.counters["frames"])
        eval_env = make_eval_env(
            self.env_factory, cfg.seed + 10_000, log.eval_episodes, cfg.env.force
        )
        if cfg.collector.total_frames > self.counters["frames"]:
            self._collect(logger, eval_env)
        last = self.eval_history[-1] if self.eval_history else {"frames": -1}
        if last["frames"] == self.counters["frames"]:  # the last batch's evaluation was the final
            summary = {k: v for k, v in last.items() if k != "frames"}
        else:
            summary = self._evaluate(logger, eval_env)
        self.save()
        (self.run_dir / DONE_MARKER).write_text("done\n")
        logger.close()
        eval_env.close()
        return summary

    def _collect(self, logger: RunLogger, eval_env: Any) -> None:
        cfg, c, col = self.cfg, self.counters, self.cfg.collector
        policy = self.builder.make_policy(self.learner)
        random_left = max(col.init_random_frames - c["frames"], 0)
        frames_left = col.total_frames - c["frames"]
        seed = cfg.seed + c["frames"]
        collector = make_collector(col, self.env_factory, policy, frames_left, random_left, seed)
        try:
            self._collect_with(collector, seed, logger, eval_env)
        finally:  # also on a worker's error: no env processes or Ray actors left behind
            collector.shutdown()

    def _collect_with(self, collector: Any, seed: int, logger: RunLogger, eval_env: Any) -> None:
        cfg, c, col = self.cfg, self.counters, self.cfg.collector
        collector.set_seed(seed)
        if col.kind == "ray":
            collector.update_policy_weights_()  # workers start from the learner's current actor
        next_sync = c["updates"] + col.weight_sync_every
        tracker, recent = EpisodeStats(self.rewards.reward_keys), deque(maxlen=20)
        pending: dict[str, list[float]] = defaultdict(list)
        bar = tqdm(
            total=col.total_frames,
            initial=c["frames"],
            disable=not cfg.logging.progress,
            unit="frame",
        )
        start, start_frames = time.perf_counter(), c["frames"]
        for batch in collector:
            batch = self.rewards.transform(batch)
            guards.check_rewards(batch, self.rewards.reward_keys, c["frames"], self.ckpt)
            c["frames"] += batch.numel()
            for ep in tracker.update(batch):
                logger.log({f"episode/{k}": v for k, v in ep.items()}, c["frames"])
                recent.append(ep)
            batch = batch.exclude(*EPISODE_KEYS, *[("next", k) for k in EPISODE_KEYS])
            self.rewards.extend(batch)
            rewards = [("next", k) for k in self.rewards.reward_keys]
            self.writer.extend(batch.select(*AGENT_KEYS, *rewards))
            if c["frames"] > col.init_random_frames and len(self.rb) >= cfg.replay.batch_size:
                c["update_credit"] += cfg.learner.utd_ratio * batch.numel()
                while c["update_credit"] >= 1:
                    c["update_credit"] -= 1
                    for k, v in self.update().items():
                        pending[k].append(v)
                if col.kind == "multi" or (col.kind == "ray" and c["updates"] >= next_sync):
                    collector.update_policy_weights_()
                    next_sync = c["updates"] + col.weight_sync_every
            fps = (c["frames"] - start_frames) / max(time.perf_counter() - start, 1e-9)
            self._report(logger, eval_env, pending, fps, batch.numel())
            bar.update(batch.numel())
            bar.set_postfix(progress_postfix(recent, self.eval_history))
        bar.close()

    def update(self) -> dict[str, float]:
        """One update: every model (then the rewards' schedule), then the D4PG learner."""
        with timeit("update"):
            metrics = self.rewards.update(self.counters["updates"] + 1)
            batch = self.rb.sample()
            metrics.update(self.rewards.refresh(batch, self.cfg.learner.gamma))
            out = self.learner.update(batch)
            self.rb.update_tensordict_priority(batch)
            if self.beta_schedule is not None:
                self.beta_schedule.step()
        self.counters["updates"] += 1
        metrics.update({k: v.item() for k, v in out.items()})
        for key in self.rewards.reward_keys:
            metrics[f"batch_{key}"] = batch.get(("next", key)).mean().item()
        where = f"frame {self.counters['frames']} (update {self.counters['updates']})"
        guards.stop_if_not_finite(metrics, where, self.ckpt)
        return metrics

    def _report(
        self,
        logger: RunLogger,
        eval_env: Any,
        pending: dict[str, list[float]],
        fps: float,
        batch_frames: int,
    ) -> None:
        """Log averaged update metrics, env speed; evaluate and checkpoint when due."""
        log, frames = self.cfg.logging, self.counters["frames"]
        if pending and len(pending["loss_value"]) >= log.log_every_updates:
            scalars = {f"train/{k}": float(np.mean(v)) for k, v in pending.items()}
            scalars["train/intrinsic_on"] = float(self.rewards.intrinsic_on)
            # Model + learner updates per second of update time (collection excluded).
            scalars["train/updates_per_s"] = 1.0 / max(timeit.todict()["update"], 1e-9)
            logger.log(scalars, frames)
            pending.clear()
            timeit.erase()
        logger.log({"train/env_steps_per_s": fps}, frames)
        if _crossed(frames, batch_frames, log.eval_every_frames):
            self._evaluate(logger, eval_env)
        if _crossed(frames, batch_frames, log.checkpoint_every_frames):
            self.save()

    def _evaluate(self, logger: RunLogger, eval_env: Any) -> dict[str, float]:
        episodes = self.cfg.logging.eval_episodes
        rollouts = rollout_episodes(eval_env, self.learner.actor, episodes, self.max_steps)
        summary, per_episode = summarize_episodes(rollouts)
        frames = self.counters["frames"]
        logger.log({f"eval/{k}": v for k, v in summary.items()}, frames)
        # The same episodes: each critic head's predicted Q against its realised return.
        loss, gamma = self.learner.loss, self.cfg.learner.gamma
        calibration = measure_calibration(loss, self.rewards.transform, rollouts, gamma)
        logger.log(calibration_scalars(calibration), frames)
        logger.log_eval_episodes(frames, per_episode)
        self.eval_history.append({"frames": frames, **summary})
        self._keep_best({"frames": frames, **summary})
        return summary

    def _keep_best(self, result: dict[str, float]) -> None:
        """Save the actor to :data:`BEST_POLICY` when this evaluation beats every earlier one.

        DDPG policies can lose a solved task later in training (docs/REPRODUCTION.md), so the
        best one (:func:`~gentlerl.training.evaluation.rank`) is kept apart from the last one.
        """
        if self.best_eval is not None and rank(result) <= rank(self.best_eval):
            return
        self.best_eval = dict(result)
        state = {**self._policy_state(), "eval": self.best_eval}
        save_checkpoint(self.run_dir / BEST_POLICY, state)

    # -- state ---------------------------------------------------------------------------
    def _policy_state(self) -> dict[str, Any]:
        """What :func:`~gentlerl.training.checkpoint.load_policy` reads: config, sizes, actor."""
        return {
            "config": self.cfg.to_dict(),
            "obs_dim": self.builder.obs_dim,
            "action_dim": self.builder.action_dim,
            "actor": self.learner.actor.state_dict(),
        }

    def state_dict(self) -> dict[str, Any]:
        """Everything a resumed run needs; the replay buffers only with ``checkpoint_buffer``."""
        keep = self.cfg.logging.checkpoint_buffer
        buffer = self.rewards.buffer if keep else None
        return {
            **self._policy_state(),
            "learner": dataclasses.asdict(self.learner.state),
            "supports": critic_supports(self.learner.loss.value_network),
            "intrinsic": self.rewards.state_dict(),
            "rb": replay_buffer_state(self.rb) if keep else None,
            "nstep": self.writer.state_dict() if keep else None,
            "model_rb": replay_buffer_state(buffer) if buffer is not None else None,
            "beta_schedule": self.beta_schedule.state_dict() if self.beta_schedule else None,
            "counters": dict(self.counters),
            "eval_history": list(self.eval_history),
            "best_eval": self.best_eval,
            "rng": rng_state(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        check_critic_supports(state, self.learner.loss.value_network, self.ckpt)
        self.learner.restore(TrainingState(**state["learner"]))
        self.rewards.load_state_dict(state["intrinsic"])
        if state["rb"] is not None:  # saved with checkpoint_buffer=false: start empty, refill
            load_replay_buffer_state(self.rb, state["rb"])
            self.writer.load_state_dict(state["nstep"])
        if self.rewards.buffer is not None and state["model_rb"] is not None:
            load_replay_buffer_state(self.rewards.buffer, state["model_rb"])
        if self.beta_schedule is not None:
            self.beta_schedule.load_state_dict(state["beta_schedule"])
        self.counters = dict(state["counters"])
        self.eval_history = list(state["eval_history"])
        self.best_eval = state["best_eval"]
        set_rng_state(state["rng"])

    def save(self) -> None:
        save_checkpoint(self.run_dir / CHECKPOINT, self.state_dict())


def _crossed(frames: int, batch_frames: int, every: int) -> bool:
    """Whether the last batch reached a multiple of ``every`` frames."""
    return frames // every > (frames - batch_frames) // every


def train(cfg: TrainConfig, env_factory: EnvFactory | None = None) -> dict[str, float]:
    """Train (or, with ``cfg.resume``, continue) a run; returns the final evaluation summary.

    ``env_factory`` builds the env (default: :func:`gentlerl.envs.make_env` for ``cfg.task``, or
    the external env ``cfg.env.name``); it must write ``observation`` and the force key
    ``cfg.env.force`` of ``ImpactPenalty``, and may write ``success`` and ``broken`` (without
    them, evaluations are ranked by their return).
    """
    validate(cfg)  # before the lock: a refused config creates nothing
    with RunLock(cfg.run_dir):  # one writer per run directory
        return Trainer(cfg, env_factory).run()
