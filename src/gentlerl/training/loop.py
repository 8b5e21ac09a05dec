"""The one training loop shared by every recipe, in the shape of a TorchRL sota script.

Set-up is a row of builders (:mod:`gentlerl.training.builders`): the process, the agent from a
probed env, the config file, the logger, the evaluation env, the collector. Then each batch goes
collect -> reward transforms -> buffers -> (model updates -> schedule) -> D4PG update -> log ->
evaluate -> checkpoint. The models learn from 1-step transitions (:class:`IntrinsicRewards`), the
learner from n-step ones (the prioritised buffer, written through an ``NStepWriter``). Updates
start after ``init_random_frames``; each frame then earns ``utd_ratio`` updates. Files go where
:class:`~gentlerl.config.layout.RunLayout` names.

A :class:`Trainer` is one seed's run: its state and each batch's steps. Its :meth:`~Trainer.run`
is a :class:`~gentlerl.training.lockstep.Lockstep` of one seed, the driver that also runs several
seeds in one process with each update one step of all of them.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl import timeit
from torchrl.envs import EnvBase

from gentlerl.agent.builder import configured_learner
from gentlerl.config.layout import RunLayout
from gentlerl.deprecation import warn_deprecated
from gentlerl.distributed.cluster import join_cluster
from gentlerl.files import write_atomic
from gentlerl.training import resume, run_eval, run_state, stops
from gentlerl.training.builders import (
    AGENT_KEYS,
    EnvFactory,
    RunCollector,
    default_env_factory,
    make_agent,
    make_logger,
    make_run_collector,
    make_run_eval_env,
    prepare_process,
    write_config,
)
from gentlerl.training.checkpoint import remove_stale_temp_files, save_checkpoint
from gentlerl.training.checkpoint_schema import check_trainer_state
from gentlerl.training.config import TrainConfig, validate
from gentlerl.training.env_probe import probe_env
from gentlerl.training.lockstep import Lockstep, LoopPass
from gentlerl.training.logging import EPISODE_KEYS, Progress, RunLogger, force_unit
from gentlerl.training.run_lock import RunLock
from gentlerl.training.seeding import rng_state

if TYPE_CHECKING:
    from gentlerl.agent import Learner
    from gentlerl.objectives import MultiHeadD4PGLoss


class Trainer:
    """One seed's run: its state, and each batch's steps; :meth:`run` executes (or resumes) it.
    See :func:`train`, which validates the config and probes the env once and passes the probe;
    without one, both are done here. In a :class:`~gentlerl.training.lockstep.Lockstep` of
    several seeds its :attr:`learner` is the seeds' one, its own row :attr:`seat`."""

    def __init__(
        self, cfg: TrainConfig, env_factory: EnvFactory | None = None, probe: EnvBase | None = None
    ) -> None:
        if probe is None:  # built directly, not by train(), which has checked and probed
            validate(cfg)
        self.cfg, self.layout = cfg, RunLayout(cfg.run_dir)
        self.env_factory = env_factory or default_env_factory(cfg)
        probe = probe if probe is not None else probe_env(cfg, self.env_factory)
        # Before anything is written: a refused resume leaves no trace in the run directory.
        self.resume_state = resume.load_resume_state(cfg, self.layout.checkpoint)
        prepare_process(cfg)
        agent = make_agent(cfg, self.env_factory, probe)
        if cfg.collector.kind == "ray":  # Ray installed and the cluster reachable, or no run
            join_cluster(cfg.collector.ray_address)
        self.layout.root.mkdir(parents=True, exist_ok=True)
        self.builder, self.rewards, self._loss = agent.builder, agent.rewards, agent.loss
        self._learner: Learner | None = None  # built on first use, or a group's given
        self.seat = 0  # this seed's row of the learner's and the models' stacked parameters
        self.writer, self.rb, self.beta_schedule = agent.writer, agent.rb, agent.beta_schedule
        self.counters = {"frames": 0, "updates": 0, "update_credit": 0.0}
        self.wall_s = 0.0  # training wall clock, resumes included (``train/wall_s``)
        self.eval_history: list[dict[str, float]] = []
        self.best_eval: dict[str, float] | None = None
        #: This run's random streams between its steps (a group's seeds each draw from their own).
        self.rng = rng_state()

    # -- the run -------------------------------------------------------------------------
    def run(self) -> dict[str, float]:
        """Collect up to ``collector.total_frames``, evaluate the last actor, write ``DONE``;
        a finished run is not run again (its final evaluation is returned)."""
        return Lockstep([self]).run()[0]

    def update(self) -> dict[str, float]:
        """Deprecated since 0.2.0 (removed in 0.3.0): one update of this run, as
        :meth:`Lockstep.update <gentlerl.training.lockstep.Lockstep.update>` of it alone."""
        warn_deprecated("Trainer.update()", "Lockstep([trainer]).update()")
        return Lockstep([self]).update()[0]

    @property
    def policy(self) -> torch.nn.Module:
        """This seed's acting actor (on the CPU)."""
        return self.learner.policy_of(self.seat)

    @property
    def loss(self) -> MultiHeadD4PGLoss:
        """This seed's D4PG loss (its actor, critics and their targets)."""
        return self._loss

    @property
    def learner(self) -> Learner:
        """The learner of this seed's :attr:`loss`: a seed group's (its row :attr:`seat`), else
        its own, built on first use."""
        if self._learner is None:
            self._learner = configured_learner(self._loss, self.cfg.learner)
        return self._learner

    @learner.setter
    def learner(self, learner: Learner) -> None:
        self._learner = learner

    def open(self) -> tuple[dict[str, float] | None, RunLogger | None, EnvBase | None]:
        """Resume (a finished run: its final evaluation, nothing opened), then the logger and
        the evaluation env."""
        remove_stale_temp_files(self.layout.root)
        finished = self._resume()
        if finished is not None:
            return finished, None, None
        logger = make_logger(self.cfg, write_config(self.cfg, self.layout))
        logger.truncate_after(self.counters["frames"])
        return None, logger, make_run_eval_env(self.cfg, self.env_factory)

    def close(self, logger: RunLogger, eval_env: EnvBase) -> dict[str, float]:
        """The final evaluation, the checkpoint and ``DONE``; closes what :meth:`open` opened."""
        summary = run_eval.final_evaluation(self, logger, eval_env)
        self.save()
        write_atomic(self.layout.done, "done\n")
        logger.close()
        eval_env.close()
        return summary

    def _resume(self) -> dict[str, float] | None:
        """Load the checkpoint found at start (its safe config changes recorded); a finished
        run's final evaluation instead."""
        if self.resume_state is None:
            return None
        state, self.resume_state = self.resume_state, None
        # every entry checked first: a NaN frame count must not read as a finished run
        check_trainer_state(self, state, self.layout.checkpoint)
        finished = resume.finished_summary(state, self.layout.done, self.cfg)
        if finished is None:
            self.load_state_dict(state)
            resume.record_config_changes(self.layout.root, state, self.cfg.to_dict())
        return finished

    def make_collector(self) -> RunCollector:
        """The run's collector, acting with the learner's policy, from the frames so far."""
        policy, frames = self.builder.make_policy(self.learner, self.seat), self.counters["frames"]
        return make_run_collector(self.cfg, self.env_factory, policy, frames)

    def start_pass(
        self,
        collector: RunCollector,
        logger: RunLogger,
        eval_env: EnvBase,
        bar: int | None = None,
    ) -> LoopPass:
        """The state of one pass of the loop over ``collector`` (``bar``: its progress bar's
        line, labelled with the seed, where several runs show theirs at once)."""
        cfg = self.cfg
        progress = Progress(
            self.rewards.reward_keys, cfg.collector.total_frames, self.counters["frames"],
            cfg.logging.progress, force_unit(cfg.env.force_scale),
            bar=None if bar is None else (bar, f"seed {cfg.seed}"),
            tolerance=cfg.gentleness.tolerance,
        )  # fmt: skip
        next_sync = self.counters["updates"] + cfg.collector.weight_sync_every
        return LoopPass(collector, logger, eval_env, progress, self.wall_s, next_sync)

    def take(self, batch: TensorDictBase, p: LoopPass) -> int:
        """A collected batch rewarded, its episodes logged (and steered on), stored; its frames."""
        batch = self._rewarded(batch)
        episodes = p.progress.finished_episodes(batch)
        for episode in episodes:
            p.logger.log({f"episode/{k}": v for k, v in episode.items()}, self.counters["frames"])
        run_eval.steer(self, episodes, p.logger, p.eval_env)
        self._store(batch)
        return batch.numel()

    def finish_batch(self, frames: int, p: LoopPass) -> None:
        """After a batch's updates: the actors synced, logs, evaluation and checkpoint when due."""
        cfg, c = self.cfg, self.counters
        if self.learning():
            self.learner.sync_policy(self.seat)  # the acting copy of a GPU learner's actor
            p.next_sync = self._sync_policy(p.collector, p.next_sync)
        self._log_training(p)
        self.wall_s = p.wall + time.perf_counter() - p.start
        fps = p.progress.env_steps_per_s(c["frames"])
        p.logger.log({"train/env_steps_per_s": fps, "train/wall_s": self.wall_s}, c["frames"])
        if crossed(c["frames"], frames, cfg.logging.eval_every_frames):
            run_eval.evaluate_run(self, p.logger, p.eval_env)
        if crossed(c["frames"], frames, cfg.logging.checkpoint_every_frames):
            self.save()
        p.progress.advance(frames, self.eval_history)

    def _rewarded(self, batch: TensorDictBase) -> TensorDictBase:
        """The batch with every reward component (checked finite), counted in ``frames``."""
        frames, checkpoint = self.counters["frames"], self.layout.checkpoint
        batch = stops.rewarded(
            self.rewards.transform, batch, self.rewards.reward_keys, frames, checkpoint
        )
        self.counters["frames"] += batch.numel()
        return batch

    def _store(self, batch: TensorDictBase) -> None:
        """The models' buffer (1-step transitions) and the learner's (through the n-step writer)."""
        batch = batch.exclude(*EPISODE_KEYS, *[("next", k) for k in EPISODE_KEYS])
        self.rewards.extend(batch)
        rewards = [("next", k) for k in self.rewards.reward_keys]
        self.writer.extend(batch.select(*AGENT_KEYS, *rewards))

    def learning(self) -> bool:
        """Past ``init_random_frames``, with a batch's worth of transitions to sample."""
        c, cfg = self.counters, self.cfg
        return (
            c["frames"] > cfg.collector.init_random_frames and len(self.rb) >= cfg.replay.batch_size
        )

    def _sync_policy(self, collector: RunCollector, next_sync: int) -> int:
        """Send the actor to the workers (multi: each batch; ray: each ``weight_sync_every``
        updates); returns the update count of the next Ray sync."""
        col, updates = self.cfg.collector, self.counters["updates"]
        if col.kind == "multi" or (col.kind == "ray" and updates >= next_sync):
            collector.update_policy_weights_()
            return updates + col.weight_sync_every
        return next_sync

    def count_update(
        self, metrics: dict[str, float], out: TensorDictBase, batch: TensorDictBase
    ) -> dict[str, float]:
        """An update counted: its losses and batch rewards read into ``metrics``, checked."""
        self.counters["updates"] += 1
        metrics.update({k: v.item() for k, v in out.items()})
        for key in self.rewards.reward_keys:
            metrics[f"batch_{key}"] = batch.get(("next", key)).mean().item()
        where = f"frame {self.counters['frames']} (update {self.counters['updates']})"
        stops.stop_if_not_finite(metrics, where, self.layout.checkpoint)
        return metrics

    def _log_training(self, p: LoopPass) -> None:
        """The update metrics averaged over every ``log_every_updates`` updates, and their speed."""
        pending = p.pending
        if not pending or len(pending["loss_value"]) < self.cfg.logging.log_every_updates:
            return
        scalars = {f"train/{k}": float(np.mean(v)) for k, v in pending.items()}
        scalars["train/intrinsic_on"] = float(self.rewards.intrinsic_on)
        # Model + learner updates per second of update time (collection excluded).
        scalars["train/updates_per_s"] = 1.0 / max(timeit.todict()["update"], 1e-9)
        p.logger.log(scalars, self.counters["frames"])
        pending.clear()

    # -- state ---------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Everything a resumed run needs (:func:`~gentlerl.training.run_state.trainer_state`)."""
        return run_state.trainer_state(self)

    def load_state_dict(self, state: dict[str, Any]) -> None:
        run_state.load_trainer_state(self, state)

    def save(self) -> None:
        save_checkpoint(self.layout.checkpoint, self.state_dict())


def crossed(frames: int, batch_frames: int, every: int) -> bool:
    """Whether the last batch reached a multiple of ``every`` frames."""
    return frames // every > (frames - batch_frames) // every


def train(cfg: TrainConfig, env_factory: EnvFactory | None = None) -> dict[str, float]:
    """Train (or, with ``cfg.resume``, continue) a run; returns the final evaluation summary.

    ``env_factory`` (default: the hand task ``cfg.task`` or the external env ``cfg.env.name``)
    must write ``observation`` and the force ``cfg.env.force``, and may write ``success`` and
    ``broken`` (without them, evaluations are ranked by their return)."""
    validate(cfg)  # before the lock: a refused config or env creates nothing
    env_factory = env_factory or default_env_factory(cfg)
    probe = probe_env(cfg, env_factory)
    with RunLock(cfg.run_dir):  # one writer per run directory
        return Trainer(cfg, env_factory, probe).run()
