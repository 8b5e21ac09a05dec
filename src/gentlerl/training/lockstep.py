"""Several seeds' runs in lockstep, their updates one step: the loop's driver.

:class:`Lockstep` runs S seeds' :class:`~gentlerl.training.loop.Trainer` s (S = 1 for
``gentlerl train``) over one collector each: each batch is rewarded, stored, logged and
evaluated per seed, and each update is one step of every seed: the S reward models of each kind
as one :class:`~gentlerl.rewards.model_step.ModelStep`, the r^sp re-scoring through one
:class:`~gentlerl.rewards.window_rescore.WindowRescorer`, the S D4PG learners as one
:class:`~gentlerl.agent.Learner` (parameters with a leading seed axis).
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from tensordict import TensorDictBase
from torchrl import timeit
from torchrl.envs import EnvBase

from gentlerl.agent.builder import configured_learner
from gentlerl.models.stacking import seed_stack
from gentlerl.rewards.model_step import ModelStep
from gentlerl.rewards.window_rescore import WindowRescorer
from gentlerl.training import stops
from gentlerl.training.logging import Progress, RunLogger
from gentlerl.training.run_lock import RunLock, held_here
from gentlerl.training.seeding import own_stream

if TYPE_CHECKING:
    from gentlerl.training.builders import RunCollector
    from gentlerl.training.seed_run import SeedRun

#: What one seed's step returns.
R = TypeVar("R")


@dataclass
class LoopPass:
    """One pass of the loop: what it collects from and logs to, its clocks and pending logs."""

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
    random streams (python's, numpy's and torch's generators swapped in around them:
    :func:`~gentlerl.training.seeding.own_stream`), and the batched updates draw nothing, so a
    seed of a group logs what it logs alone, to the float rounding of the vmapped step (tested
    to 1e-5 over 50 updates). Per seed, not batched: collection, the replay's sample and priority
    update, evaluations.
    """

    def __init__(self, trainers: Sequence[SeedRun]) -> None:
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
        built once, here (no seed builds its own)."""
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
            trainer.learner, trainer.seat = learner, seat
            trainer.rewards.share_steps(steps, seat)

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
        opened = [self._as(trainer, trainer.open) for trainer in self.trainers]
        finished = [summary for summary, _, _ in opened]
        if all(summary is not None for summary in finished):
            return finished
        if any(summary is not None for summary in finished):
            done = [t.cfg.seed for t, f in zip(self.trainers, finished, strict=True) if f]
            raise ValueError(f"seeds {done} finished, the others did not: resume each on its own")
        first = self.trainers[0]
        if first.cfg.collector.total_frames > first.counters["frames"]:
            self._collect([(logger, eval_env) for _, logger, eval_env in opened])
        return [
            self._as(trainer, trainer.close, logger, eval_env)
            for trainer, (_, logger, eval_env) in zip(self.trainers, opened, strict=True)
        ]

    @staticmethod
    def _as(trainer: SeedRun, step: Callable[..., R], *args: object) -> R:
        """``step(*args)`` of one seed, drawing from its own random streams."""
        with own_stream(trainer):
            return step(*args)

    def _collect(self, opened: list[tuple[RunLogger, EnvBase]]) -> None:
        """Each seed's collector made, the loop run over them, every collector shut down."""
        collectors: list[RunCollector] = []
        several = len(self.trainers) > 1
        try:
            collectors.extend(self._as(t, t.make_collector) for t in self.trainers)
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
        """collect -> rewards -> buffers -> updates -> log -> evaluate -> checkpoint."""
        streams = [iter(c) for c in collectors]
        while batches := self._next_batches(streams):
            seeds = list(zip(self.trainers, batches, passes, strict=True))
            frames = [self._as(t, t.take, b, p) for t, b, p in seeds]
            if all(t.learning() for t in self.trainers):
                self._earn_updates(frames[0], passes)
            for (trainer, _, p), n in zip(seeds, frames, strict=True):
                self._as(trainer, trainer.finish_batch, n, p)
            if not passes[0].pending:  # the training logs were written: the timer restarts
                timeit.erase()
        for p in passes:
            p.progress.close()

    def _next_batches(self, streams: list[Iterator[TensorDictBase]]) -> list[TensorDictBase]:
        """Each seed's next collected batch (its own random streams: its exploration noise);
        ``[]`` once the collectors are done (together: every seed collects the same frames)."""
        batches = [
            self._as(t, next, it, None) for t, it in zip(self.trainers, streams, strict=True)
        ]
        return [] if any(b is None for b in batches) else batches

    def _earn_updates(self, frames: int, passes: list[LoopPass]) -> None:
        """``utd_ratio`` updates per collected frame of each seed (fractions carried over)."""
        for trainer in self.trainers:
            trainer.counters["update_credit"] += trainer.cfg.learner.utd_ratio * frames
        while self.trainers[0].counters["update_credit"] >= 1:
            for trainer in self.trainers:
                trainer.counters["update_credit"] -= 1
            for p, metrics in zip(passes, self.update(), strict=True):
                for k, v in metrics.items():
                    p.pending[k].append(v)

    def update(self) -> list[dict[str, float]]:
        """One update of every seed: its models (then the rewards' schedule), r^sp re-scored on
        its sampled windows, then its D4PG learner; each kind as one step."""
        trainers = self.trainers
        with timeit("update"):
            metrics: list[dict[str, float]] = [{} for _ in trainers]
            samples = [self._as(t, _samples, t) for t in trainers]  # each from its own streams
            model_batches = [models for models, _ in samples]
            for name, step in self.models.items():
                losses = step(seed_stack([b[name] for b in model_batches])).tolist()
                for seed_metrics, loss in zip(metrics, losses, strict=True):
                    seed_metrics[f"model_{name}"] = loss
            for trainer in trainers:
                trainer.rewards.step(trainer.counters["updates"] + 1)
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


def _samples(trainer: SeedRun) -> tuple[dict[str, TensorDictBase], TensorDictBase]:
    """One update's draws of a seed, in a lone run's order: its models' batches, then its
    learner's prioritised batch (neither step in between draws)."""
    return trainer.rewards.model_batches(), trainer.rb.sample()
