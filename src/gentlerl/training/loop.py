"""The training loop, in one file, in the shape of a TorchRL sota script: :class:`Lockstep`.

Set-up is a row of builders (:mod:`gentlerl.training.builders`): the process, the agent from a
probed env, the config file, the logger, the evaluation env, the collector. Then, for S seeds
at once (S = 1 for ``gentlerl train``), :meth:`Lockstep._loop` runs each batch top to bottom:
collect -> reward transforms -> extend the buffers -> (sample -> model updates -> schedule ->
re-score -> D4PG update -> priorities) x ``utd_ratio`` -> log -> evaluate -> checkpoint. The
models learn from 1-step transitions (:class:`IntrinsicRewards`), the learner from n-step ones
(the prioritised buffer, written through an ``NStepWriter``). Updates start after
``init_random_frames``; each frame then earns ``utd_ratio`` updates. Files go where
:class:`~gentlerl.config.layout.RunLayout` names.

A :class:`Trainer` is one seed's run: its parts (networks, buffers, reward transforms, files) and
its :class:`RunState`, with the steps that touch only that seed (reward and store a batch,
evaluate, steer the penalty, save). The seeds' updates are one: one
:class:`~gentlerl.agent.Learner` and one :class:`~gentlerl.rewards.model_step.ModelStep` per model
kind over every seed's networks (parameters with a leading seed axis), seed s row s.
"""

from __future__ import annotations

import dataclasses
import time
from collections import defaultdict
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl import timeit
from torchrl.envs import EnvBase

from gentlerl.agent.builder import configured_learner
from gentlerl.agent.learner import TrainingState
from gentlerl.config.layout import RunLayout
from gentlerl.deprecation import warn_deprecated
from gentlerl.distributed.cluster import join_cluster
from gentlerl.files import write_atomic
from gentlerl.models.stacking import seed_stack
from gentlerl.rewards.model_step import ModelStep
from gentlerl.rewards.window_rescore import WindowRescorer
from gentlerl.training import resume, stops
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
from gentlerl.training.checkpoint import (
    check_critic_supports,
    critic_supports,
    load_replay_buffer_state,
    remove_stale_temp_files,
    replay_buffer_state,
    save_checkpoint,
)
from gentlerl.training.checkpoint_schema import check_trainer_state
from gentlerl.training.config import TrainConfig, validate
from gentlerl.training.critic_calibration import evaluation_scalars
from gentlerl.training.env_probe import probe_env
from gentlerl.training.evaluation import evaluate, rank, rollout_episodes, summarize_episodes
from gentlerl.training.logging import EPISODE_KEYS, Progress, RunLogger, force_unit
from gentlerl.training.run_lock import RunLock, held_here
from gentlerl.training.seeding import rng_state, set_rng_state

if TYPE_CHECKING:
    from gentlerl.agent import Learner
    from gentlerl.objectives import MultiHeadD4PGLoss


@dataclass
class RunState:
    """What one seed's run has done, as its checkpoint keeps it (with its networks and buffers)."""

    frames: int = 0  #: collected env steps
    updates: int = 0  #: D4PG updates
    update_credit: float = 0.0  #: updates earned (``utd_ratio`` a frame) and not yet made
    wall_s: float = 0.0  #: training wall clock, resumes included (``train/wall_s``)
    eval_history: list[dict[str, float]] = field(default_factory=list)
    best_eval: dict[str, float] | None = None
    #: Its random streams between its steps (:func:`own_stream`; each seed of a group its own).
    rng: dict[str, Any] = field(default_factory=rng_state)

    @property
    def counters(self) -> dict[str, Any]:
        """``frames``, ``updates``, ``update_credit``: a checkpoint's ``counters``."""
        return {"frames": self.frames, "updates": self.updates, "update_credit": self.update_credit}


@contextmanager
def own_stream(state: RunState) -> Iterator[None]:
    """Within: the process's generators hold ``state.rng``; after: the state they reached is
    kept there. Each seed of a group draws from its own continuing stream, as it would alone,
    whatever the other seeds draw in between."""
    set_rng_state(state.rng)
    try:
        yield
    finally:
        state.rng = rng_state()


@dataclass
class LoopPass:
    """One seed's pass of the loop: what it collects from and logs to, its clocks and pending
    training logs."""

    collector: RunCollector
    logger: RunLogger
    eval_env: EnvBase
    progress: Progress
    wall: float
    next_sync: int
    start: float = field(default_factory=time.perf_counter)
    pending: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))


class Lockstep:
    """The runs of ``trainers`` (one variant and its settings, a seed each) in lockstep:
    :meth:`run`.

    Each seed keeps what a run of its own has: its env stream (its collector, seeded by its
    seed), its exploration noise, replay buffers, reward transforms, evaluations, logs and
    checkpoints in its own run directory. Their updates are one: with several seeds, one
    :class:`~gentlerl.agent.Learner` and one :class:`~gentlerl.rewards.model_step.ModelStep` per
    model kind are built over every seed's networks, each seed training its own row, and each
    seed's checkpoint holds its own row: a run of its own. Each seed's steps draw from its own
    random streams (:func:`own_stream`), and the batched updates draw nothing, so a seed of a
    group logs what it logs alone, to the float rounding of the vmapped step (tested to 1e-5
    over 50 updates). Per seed, not batched: collection, the replay's sample and priority update,
    evaluations.
    """

    def __init__(self, trainers: Sequence[Trainer]) -> None:
        if not trainers:
            raise ValueError("Lockstep needs at least one Trainer (one per seed), got 0")
        self.trainers = list(trainers)
        dirs = [Path(t.cfg.run_dir).resolve() for t in self.trainers]
        if len(set(dirs)) != len(dirs) or len({id(t) for t in self.trainers}) != len(dirs):
            # one run dir twice: its eval rows duplicated, one checkpoint over the other
            raise ValueError(
                f"each seed needs its own run_dir, got {[str(t.cfg.run_dir) for t in trainers]}"
            )
        starts = {t.resume_state["counters"]["frames"] if t.resume_state else 0 for t in trainers}
        if len(starts) > 1:  # before anything is written
            raise ValueError(
                f"the seeds' checkpoints are at different frames {sorted(starts)}: resume each "
                "seed on its own, or start the group in new run_dirs"
            )
        if len(self.trainers) > 1:
            self._share()
        self.learner = self.trainers[0].learner
        self.models = self.trainers[0].rewards.steps
        self.rescorer = WindowRescorer([t.rewards for t in self.trainers])
        self._priority_key = self.learner.loss.tensor_keys.priority

    def _share(self) -> None:
        """One learner and one step per model kind over every seed's networks, seed s row s:
        built once, here (no seed builds its own), and each seed seated in them."""
        trainers, cfg = self.trainers, self.trainers[0].cfg
        launch = {"compile": cfg.learner.compile, "cudagraphs": cfg.learner.cudagraphs}
        learner = configured_learner([t.loss for t in trainers], cfg.learner)
        steps = {
            name: ModelStep(
                [t.rewards.losses[name] for t in trainers], cfg.gentleness.lr_model, **launch
            )
            for name in trainers[0].rewards.losses
        }
        for seat, trainer in enumerate(trainers):
            trainer.take_seat(learner, steps, seat)

    def run(self) -> list[dict[str, float]]:
        """Every seed's run to ``collector.total_frames`` (resumed where its checkpoint is);
        each seed's final evaluation (a finished run's is read, not run again). Each run
        directory's lock is held meanwhile (:class:`~gentlerl.training.run_lock.RunLock`; one
        its caller holds is kept)."""
        with ExitStack() as locks:
            for trainer in self.trainers:
                if not held_here(trainer.cfg.run_dir):
                    locks.enter_context(RunLock(trainer.cfg.run_dir))
            return self._run()

    def _run(self) -> list[dict[str, float]]:
        """Open every seed's run (resumed), the loop, close each (final evaluation, ``DONE``)."""
        opened = []
        for trainer in self.trainers:
            with own_stream(trainer.state):
                opened.append(trainer.open())
        finished = [summary for summary, _, _ in opened]
        if all(summary is not None for summary in finished):
            return finished
        if any(summary is not None for summary in finished):
            done = [t.cfg.seed for t, f in zip(self.trainers, finished, strict=True) if f]
            raise ValueError(f"seeds {done} finished, the others did not: resume each on its own")
        first = self.trainers[0]
        if first.cfg.collector.total_frames > first.state.frames:
            self._collect([(logger, eval_env) for _, logger, eval_env in opened])
        summaries = []
        for trainer, (_, logger, eval_env) in zip(self.trainers, opened, strict=True):
            with own_stream(trainer.state):
                summaries.append(trainer.close(logger, eval_env))
        return summaries

    def _collect(self, opened: list[tuple[RunLogger, EnvBase]]) -> None:
        """Each seed's collector made, the loop run over them, every collector shut down."""
        collectors: list[RunCollector] = []
        several = len(self.trainers) > 1
        try:
            for trainer in self.trainers:
                with own_stream(trainer.state):
                    collectors.append(trainer.make_collector())
            passes = [
                t.start_pass(c, logger, eval_env, bar=s if several else None)
                for s, (t, c, (logger, eval_env)) in enumerate(
                    zip(self.trainers, collectors, opened, strict=True)
                )
            ]
            self._loop(collectors, passes)
        except ChildProcessError as err:  # a collector process was killed: the run can go on
            raise stops.resumable_fault(err, self.trainers[0].layout.checkpoint) from err
        finally:  # also on a worker's error: no env processes or Ray actors left behind
            for collector in collectors:
                collector.shutdown()

    def _loop(self, collectors: list[RunCollector], passes: list[LoopPass]) -> None:
        """The loop: each step for every seed, each seed's own steps from its random streams."""
        seeds = list(zip(self.trainers, passes, strict=True))
        streams = [iter(collector) for collector in collectors]
        while True:
            # collect (each seed's exploration noise; together: every seed collects the same)
            batches = []
            for trainer, stream in zip(self.trainers, streams, strict=True):
                with own_stream(trainer.state):
                    batches.append(next(stream, None))
            if any(batch is None for batch in batches):
                break
            # reward transforms, the episodes logged (and steered on), extend the buffers
            frames = []
            for (trainer, p), batch in zip(seeds, batches, strict=True):
                with own_stream(trainer.state):
                    frames.append(trainer.take(batch, p))
            # sample -> models -> re-score -> D4PG, utd_ratio updates per collected frame
            if all(trainer.learning() for trainer in self.trainers):
                self._earn_updates(frames[0], passes)
            # actors synced, training logs, evaluation and checkpoint when due
            for (trainer, p), n in zip(seeds, frames, strict=True):
                with own_stream(trainer.state):
                    trainer.finish_batch(n, p)
            if not passes[0].pending:  # the training logs were written: the timer restarts
                timeit.erase()
        for p in passes:
            p.progress.close()

    def _earn_updates(self, frames: int, passes: list[LoopPass]) -> None:
        """``utd_ratio`` updates per collected frame of each seed (fractions carried over)."""
        states = [trainer.state for trainer in self.trainers]
        for trainer in self.trainers:
            trainer.state.update_credit += trainer.cfg.learner.utd_ratio * frames
        while states[0].update_credit >= 1:
            for state in states:
                state.update_credit -= 1
            for p, metrics in zip(passes, self.update(), strict=True):
                for k, v in metrics.items():
                    p.pending[k].append(v)

    def update(self) -> list[dict[str, float]]:
        """One update of every seed: its models (then the rewards' schedule), r^sp re-scored on
        its sampled windows, then its D4PG learner; each kind as one step."""
        trainers = self.trainers
        with timeit("update"):
            metrics: list[dict[str, float]] = [{} for _ in trainers]
            samples = []  # a lone run's order: the models' batches, then the prioritised batch
            for trainer in trainers:
                with own_stream(trainer.state):
                    samples.append((trainer.rewards.model_batches(), trainer.rb.sample()))
            for name, step in self.models.items():
                losses = step(seed_stack([models[name] for models, _ in samples])).tolist()
                for seed_metrics, loss in zip(metrics, losses, strict=True):
                    seed_metrics[f"model_{name}"] = loss
            for trainer in trainers:
                trainer.rewards.step(trainer.state.updates + 1)
            batches = [batch for _, batch in samples]
            stacked, rescored = self.rescorer(batches, trainers[0].cfg.learner.gamma)
            for seed_metrics, seed_rescored in zip(metrics, rescored, strict=True):
                seed_metrics.update(seed_rescored)
            out = self.learner.update(stacked)
            priority = stacked.get(self._priority_key)
            for s, (trainer, batch) in enumerate(zip(trainers, batches, strict=True)):
                batch.set(self._priority_key, priority[s])
                trainer.rb.update_tensordict_priority(batch)
                if trainer.beta_schedule is not None:
                    trainer.beta_schedule.step()
        return [
            trainer.count_update(seed_metrics, out[s], stacked[s])
            for s, (trainer, seed_metrics) in enumerate(zip(trainers, metrics, strict=True))
        ]


class Trainer:
    """One seed's run: its parts, its :class:`RunState`, and its own steps of each batch;
    :meth:`run` executes (or resumes) it. See :func:`train`, which validates the config and
    probes the env once and passes the probe; without one, both are done here. In a
    :class:`Lockstep` of several seeds its :attr:`learner` is the seeds' one, its own row
    :attr:`seat` (:meth:`take_seat`)."""

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
        self.state = RunState()  # its random streams: the process's, as set up above

    # -- the run -------------------------------------------------------------------------
    def run(self) -> dict[str, float]:
        """Collect up to ``collector.total_frames``, evaluate the last actor, write ``DONE``;
        a finished run is not run again (its final evaluation is returned)."""
        return Lockstep([self]).run()[0]

    def update(self) -> dict[str, float]:
        """Deprecated since 0.2.0 (removed in 0.3.0): one update of this run, as
        :meth:`Lockstep.update` of it alone."""
        warn_deprecated("Trainer.update()", "Lockstep([trainer]).update()")
        return Lockstep([self]).update()[0]

    @property
    def counters(self) -> dict[str, Any]:
        """:attr:`RunState.counters` of :attr:`state`."""
        return self.state.counters

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

    def take_seat(self, learner: Learner, steps: dict[str, ModelStep], seat: int) -> None:
        """Train in a seed group's ``learner`` and model ``steps`` (built over every seed's
        networks), row ``seat`` of each, instead of a learner and steps of its own."""
        self._learner, self.seat = learner, seat
        self.rewards.share_steps(steps, seat)

    def open(self) -> tuple[dict[str, float] | None, RunLogger | None, EnvBase | None]:
        """Resume (a finished run: its final evaluation, nothing opened), then the logger and
        the evaluation env."""
        remove_stale_temp_files(self.layout.root)
        finished = self._resume()
        if finished is not None:
            return finished, None, None
        logger = make_logger(self.cfg, write_config(self.cfg, self.layout))
        logger.truncate_after(self.state.frames)
        return None, logger, make_run_eval_env(self.cfg, self.env_factory)

    def close(self, logger: RunLogger, eval_env: EnvBase) -> dict[str, float]:
        """The final evaluation (the last batch's where it was at the final frame), the
        checkpoint and ``DONE``; closes what :meth:`open` opened."""
        last = self.state.eval_history[-1] if self.state.eval_history else {"frames": -1}
        if last["frames"] == self.state.frames:
            summary = {k: v for k, v in last.items() if k != "frames"}
        else:
            summary = self._evaluate(logger, eval_env)
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
        policy = self.builder.make_policy(self.learner, self.seat)
        return make_run_collector(self.cfg, self.env_factory, policy, self.state.frames)

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
            self.rewards.reward_keys, cfg.collector.total_frames, self.state.frames,
            cfg.logging.progress, force_unit(cfg.env.force_scale),
            bar=None if bar is None else (bar, f"seed {cfg.seed}"),
            tolerance=cfg.gentleness.tolerance,
        )  # fmt: skip
        next_sync = self.state.updates + cfg.collector.weight_sync_every
        return LoopPass(collector, logger, eval_env, progress, self.state.wall_s, next_sync)

    # -- its steps of each batch ---------------------------------------------------------
    def take(self, batch: TensorDictBase, p: LoopPass) -> int:
        """A collected batch rewarded (every component checked finite), its episodes logged
        (and steered on), stored: the models' buffer (1-step transitions) and the learner's
        (through the n-step writer); its frames."""
        frames, checkpoint = self.state.frames, self.layout.checkpoint
        batch = stops.rewarded(
            self.rewards.transform, batch, self.rewards.reward_keys, frames, checkpoint
        )
        self.state.frames += batch.numel()
        episodes = p.progress.finished_episodes(batch)
        for episode in episodes:
            p.logger.log({f"episode/{k}": v for k, v in episode.items()}, self.state.frames)
        self._steer(episodes, p.logger, p.eval_env)
        batch = batch.exclude(*EPISODE_KEYS, *[("next", k) for k in EPISODE_KEYS])
        self.rewards.extend(batch)
        rewards = [("next", k) for k in self.rewards.reward_keys]
        self.writer.extend(batch.select(*AGENT_KEYS, *rewards))
        return batch.numel()

    def learning(self) -> bool:
        """Past ``init_random_frames``, with a batch's worth of transitions to sample."""
        cfg = self.cfg
        past = self.state.frames > cfg.collector.init_random_frames
        return past and len(self.rb) >= cfg.replay.batch_size

    def count_update(
        self, metrics: dict[str, float], out: TensorDictBase, batch: TensorDictBase
    ) -> dict[str, float]:
        """An update counted: its losses and batch rewards read into ``metrics``, checked."""
        self.state.updates += 1
        metrics.update({k: v.item() for k, v in out.items()})
        for key in self.rewards.reward_keys:
            metrics[f"batch_{key}"] = batch.get(("next", key)).mean().item()
        where = f"frame {self.state.frames} (update {self.state.updates})"
        stops.stop_if_not_finite(metrics, where, self.layout.checkpoint)
        return metrics

    def finish_batch(self, frames: int, p: LoopPass) -> None:
        """After a batch's updates: the actors synced, logs, evaluation and checkpoint when due."""
        cfg, state = self.cfg, self.state
        if self.learning():
            self.learner.sync_policy(self.seat)  # the acting copy of a GPU learner's actor
            p.next_sync = self._sync_policy(p.collector, p.next_sync)
        self._log_training(p)
        state.wall_s = p.wall + time.perf_counter() - p.start
        fps = p.progress.env_steps_per_s(state.frames)
        p.logger.log({"train/env_steps_per_s": fps, "train/wall_s": state.wall_s}, state.frames)
        if crossed(state.frames, frames, cfg.logging.eval_every_frames):
            self._evaluate(p.logger, p.eval_env)
        if crossed(state.frames, frames, cfg.logging.checkpoint_every_frames):
            self.save()
        p.progress.advance(frames, state.eval_history)

    def _sync_policy(self, collector: RunCollector, next_sync: int) -> int:
        """Send the actor to the workers (multi: each batch; ray: each ``weight_sync_every``
        updates); returns the update count of the next Ray sync."""
        col, updates = self.cfg.collector, self.state.updates
        if col.kind == "multi" or (col.kind == "ray" and updates >= next_sync):
            collector.update_policy_weights_()
            return updates + col.weight_sync_every
        return next_sync

    def _log_training(self, p: LoopPass) -> None:
        """The update metrics averaged over every ``log_every_updates`` updates, and their speed."""
        pending = p.pending
        if not pending or len(pending["loss_value"]) < self.cfg.logging.log_every_updates:
            return
        scalars = {f"train/{k}": float(np.mean(v)) for k, v in pending.items()}
        scalars["train/intrinsic_on"] = float(self.rewards.intrinsic_on)
        # Model + learner updates per second of update time (collection excluded).
        scalars["train/updates_per_s"] = 1.0 / max(timeit.todict()["update"], 1e-9)
        p.logger.log(scalars, self.state.frames)
        pending.clear()

    # -- evaluations and the penalty's steering --------------------------------------------
    def _evaluate(self, logger: RunLogger, eval_env: EnvBase) -> dict[str, float]:
        """``logging.eval_episodes`` noise-free episodes of the acting actor, logged (with each
        critic head's prediction against what they returned), kept, ranked."""
        cfg, frames = self.cfg, self.state.frames
        rollouts = rollout_episodes(
            eval_env, self.policy, cfg.logging.eval_episodes, self.builder.horizon
        )
        summary, per_episode = summarize_episodes(rollouts, cfg.gentleness.tolerance)
        logger.log({f"eval/{k}": v for k, v in summary.items()}, frames)
        # The same episodes: each critic head's predicted Q against its realised return.
        scalars = evaluation_scalars(self.loss, self.rewards.transform, rollouts, cfg.learner.gamma)
        logger.log(scalars, frames)
        logger.log_eval_episodes(frames, per_episode)
        self.state.eval_history.append({"frames": frames, **summary})
        self.keep_best({"frames": frames, **summary})
        return summary

    def keep_best(self, result: dict[str, float]) -> None:
        """Save the actor to ``best_policy.pt`` when this evaluation beats every earlier one
        (:func:`~gentlerl.training.evaluation.rank`): DDPG can lose a solved task later on."""
        best = self.state.best_eval
        if best is not None and rank(result) <= rank(best):
            return
        self.state.best_eval = dict(result)
        save_checkpoint(self.layout.best_policy, {**self._policy_state(), "eval": dict(result)})

    def _steer(
        self, episodes: list[dict[str, float]], logger: RunLogger, eval_env: EnvBase
    ) -> None:
        """The heads' weights after the finished ``episodes``: the penalty's
        (``gentleness.multiplier``; with ``multiplier_episodes``, after that many noise-free
        episodes at each PID step), or every head's (``multiplier=lagrangian``: the episodes'
        costs, those of the first random actions too, the warm-up keeping the multiplier)."""
        frames, rewards = self.state.frames, self.rewards
        if rewards.lagrangian is not None:
            if not episodes:
                return
            steered = rewards.lagrangian
            steered.observe([e["cost"] for e in episodes], frames)
        else:
            steered = rewards.multiplier
            if steered is None or not self.learning():
                return  # the policy's episodes only: not those of the first random actions
            if not episodes and steered.period is None:
                return  # stepped per episode
            if n := self.cfg.gentleness.multiplier_episodes:  # the deployed policy's cost
                due = steered.due(frames)
                horizon = self.builder.horizon
                episodes = evaluate(eval_env, self.policy, n, horizon)[1] if due else []
            steered.observe([e["max_impact"] for e in episodes], frames=frames)
        self._apply_head_weights()
        logger.log({f"train/{k}": v for k, v in steered.scalars().items()}, frames)

    def _apply_head_weights(self) -> None:
        """The actor's weights on the heads the run's multiplier steers, as it stands now."""
        for key, weight in self.rewards.head_weights().items():
            self.loss.set_head_weight(key, weight)

    # -- state ---------------------------------------------------------------------------
    def _policy_state(self) -> dict[str, Any]:
        """What :func:`~gentlerl.training.checkpoint.load_policy` reads: config, sizes, actor."""
        return {
            "config": self.cfg.to_dict(),
            "obs_dim": self.builder.obs_dim,
            "action_dim": self.builder.action_dim,
            "actor": self.policy.state_dict(),
        }

    def state_dict(self) -> dict[str, Any]:
        """Everything a resumed run needs: networks, optimisers, rewards' models and
        multiplier, :attr:`state`; the replay buffers only with ``checkpoint_buffer``."""
        keep, state = self.cfg.logging.checkpoint_buffer, self.state
        buffer = self.rewards.buffer if keep else None
        return {
            **self._policy_state(),
            "learner": dataclasses.asdict(self.learner.state_of(self.seat)),
            "supports": critic_supports(self.loss.value_network),
            "intrinsic": self.rewards.state_dict(),
            "rb": replay_buffer_state(self.rb) if keep else None,
            "nstep": self.writer.state_dict() if keep else None,
            "model_rb": replay_buffer_state(buffer) if buffer is not None else None,
            "beta_schedule": self.beta_schedule.state_dict() if self.beta_schedule else None,
            "counters": state.counters,
            "wall_s": state.wall_s,
            "eval_history": list(state.eval_history),
            "best_eval": state.best_eval,
            "rng": rng_state(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`'s ``state`` (its checks first: every entry against this
        run, :func:`~gentlerl.training.checkpoint_schema.check_trainer_state`)."""
        path = self.layout.checkpoint
        check_trainer_state(self, state, path)
        check_critic_supports(state, self.loss.value_network, path)
        self.learner.restore(TrainingState(**state["learner"]), self.seat)
        self.rewards.load_state_dict(state["intrinsic"])
        self._apply_head_weights()  # the objective as it was saved
        if state["rb"] is not None:  # saved with checkpoint_buffer=false: start empty, refill
            load_replay_buffer_state(self.rb, state["rb"], path)
            self.writer.load_state_dict(state["nstep"])
        if self.rewards.buffer is not None and state["model_rb"] is not None:
            load_replay_buffer_state(self.rewards.buffer, state["model_rb"], path)
        if self.beta_schedule is not None:
            self.beta_schedule.load_state_dict(state["beta_schedule"])
        counters, run = resume.checked_counters(state["counters"], path), self.state
        run.frames, run.updates = counters["frames"], counters["updates"]
        run.update_credit = counters["update_credit"]
        run.wall_s = float(state.get("wall_s", 0.0))  # absent in checkpoints before it
        run.eval_history, run.best_eval = list(state["eval_history"]), state["best_eval"]
        set_rng_state(state["rng"])

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
