"""Several seeds of one run in one process: each seed a run of its own, their updates one step.

A :class:`SeedGroup` runs S seeds' :class:`~gentlerl.training.loop.Trainer` s in lockstep. Each
seed keeps what a run of its own has: its env stream (its collector, seeded by its seed), its
exploration noise, replay buffers, reward transforms, evaluations, logs and checkpoints in its
own run directory. Their updates are one: the S reward models of each kind step as one
:class:`~gentlerl.rewards.model_step.SeedBatchedModelStep` and the S D4PG learners as one
:class:`~gentlerl.agent.seeds.SeedBatchedLearner` (``torch.vmap`` over parameters stacked on a
seed dimension), and each seed's own networks share its row of those stacks, so it acts,
evaluates and is checkpointed with no copy. Before each checkpoint every seed's own optimisers
get their rows of the batched Adam states, so a seed's checkpoint resumes as a run of its own;
a group itself does not resume (refused).

The r^sp re-scoring at sampling (each seed's target penalty model) is one vmapped forward on a
GPU and seed by seed on a CPU, where that is cheaper
(:class:`~gentlerl.rewards.seed_rescore.SeedBatchedRescore`). Per seed, not batched: collection,
the replay's sample and priority update, evaluations. A group's numbers are its own
(the seeds share the process's random stream) and reproduce themselves for the same seeds.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torchrl import timeit

from gentlerl.agent.seeds import SeedBatchedLearner
from gentlerl.config.layout import RunLayout
from gentlerl.rewards.model_step import SeedBatchedModelStep
from gentlerl.rewards.seed_rescore import SeedBatchedRescore
from gentlerl.rewards.variants import COMPONENTS, reward_keys
from gentlerl.training.builders import EnvFactory
from gentlerl.training.config import TrainConfig
from gentlerl.training.loop import LoopPass, Trainer, crossed

#: The settings in which a group's seeds may differ.
PER_SEED = ("seed", "run_dir")


def group_problems(cfgs: Sequence[TrainConfig]) -> list[str]:
    """Why ``cfgs`` cannot run as one seed group (empty: they can)."""
    if not cfgs:
        return ["a seed group needs at least one config, got 0"]
    first = {k: v for k, v in cfgs[0].to_dict().items() if k not in PER_SEED}
    problems = []
    for cfg in cfgs[1:]:
        other = {k: v for k, v in cfg.to_dict().items() if k not in PER_SEED}
        if other != first:
            keys = sorted(k for k in first if first[k] != other.get(k))
            problems.append(
                f"seed {cfg.seed}'s config differs from seed {cfgs[0].seed}'s in {keys}"
            )
    for name in PER_SEED:
        values = [str(getattr(cfg, name)) for cfg in cfgs]
        if len(set(values)) != len(values):
            problems.append(f"each seed needs its own {name}, got {values}")
    models = {COMPONENTS[key].model for key in reward_keys(cfgs[0].variant)}
    if "icm" in models:
        problems.append(
            f"variant={cfgs[0].variant!r} learns an ICM model, which a seed group does not batch "
            "(the penalty and dynamics ensembles only); run its seeds one by one"
        )
    for cfg in cfgs:  # before any seed's trainer makes its folder
        if RunLayout(cfg.run_dir).has_started():
            problems.append(
                f"run_dir={str(cfg.run_dir)!r} holds a run (a checkpoint or logs): a seed group "
                "does not resume; resume each seed's run on its own, or choose new run_dirs"
            )
    if cfgs[0].gentleness.multiplier != "none":
        problems.append(
            f"gentleness.multiplier={cfgs[0].gentleness.multiplier!r}: a seed group batches one "
            "penalty weight for every seed; run steered seeds one by one"
        )
    return problems


class SeedGroup:
    """The runs of ``cfgs`` (one variant, its seeds), trained together: :meth:`run`.

    Args:
        cfgs: one config per seed, equal but for ``seed`` and ``run_dir``.
        env_factory: as :func:`~gentlerl.training.loop.train` takes (each seed's env is seeded
            by its config's seed).
    """

    def __init__(self, cfgs: Sequence[TrainConfig], env_factory: EnvFactory | None = None) -> None:
        if problems := group_problems(cfgs):
            raise ValueError("; ".join(problems))
        self.trainers = [Trainer(cfg, env_factory) for cfg in cfgs]
        cfg = cfgs[0]
        launch = {"compile": cfg.learner.compile, "cudagraphs": cfg.learner.cudagraphs}
        self.learner = SeedBatchedLearner(
            [t.learner.loss for t in self.trainers],
            lr_actor=cfg.learner.lr_actor,
            lr_critic=cfg.learner.lr_critic,
            target_update_period=cfg.learner.target_update_period,
            share=True,
            **launch,
        )
        self.models = {
            name: SeedBatchedModelStep(
                [t.rewards.losses[name] for t in self.trainers],
                cfg.gentleness.lr_model,
                share=True,
                **launch,
            )
            for name in self.trainers[0].rewards.losses
        }
        self.rescore = SeedBatchedRescore([t.rewards for t in self.trainers])
        self._priority_key = self.trainers[0].learner.loss.tensor_keys.priority

    def run(self) -> list[dict[str, float]]:
        """Every seed's run to ``collector.total_frames``; each seed's final evaluation."""
        opened = [trainer.open() for trainer in self.trainers]
        collectors: list[Any] = []
        try:
            collectors.extend(trainer.make_collector() for trainer in self.trainers)
            passes = [
                trainer.start_pass(collector, logger, eval_env, bar=s)
                for s, (trainer, collector, (_, logger, eval_env)) in enumerate(
                    zip(self.trainers, collectors, opened, strict=True)
                )
            ]
            for p in passes:
                p.erase_timer = False
            self._loop(collectors, passes)
        finally:  # also on an error: no env processes left behind
            for collector in collectors:
                collector.shutdown()
        self._give_rows()
        return [
            trainer.close(logger, eval_env)
            for trainer, (_, logger, eval_env) in zip(self.trainers, opened, strict=True)
        ]

    def _loop(self, collectors: list[Any], passes: list[LoopPass]) -> None:
        """Each seed's batch taken, the group's updates, each seed's batch finished."""
        every = self.trainers[0].cfg.logging.checkpoint_every_frames
        for batches in zip(*collectors, strict=True):
            frames = [t.take(b, p) for t, b, p in zip(self.trainers, batches, passes, strict=True)]
            if all(t.learning() for t in self.trainers):
                self._earn_updates(frames[0], passes)
            if crossed(self.trainers[0].counters["frames"], frames[0], every):
                self._give_rows()  # the checkpoints below hold each seed's optimiser state
            for trainer, n, p in zip(self.trainers, frames, passes, strict=True):
                trainer.finish_batch(n, p)
            if not passes[0].pending:  # the training logs were written: the timer restarts
                timeit.erase()
        for p in passes:
            p.progress.close()

    def _earn_updates(self, frames: int, passes: list[LoopPass]) -> None:
        """``utd_ratio`` group updates per frame of each seed (fractions carried over)."""
        for trainer in self.trainers:
            trainer.counters["update_credit"] += trainer.cfg.learner.utd_ratio * frames
        while self.trainers[0].counters["update_credit"] >= 1:
            for trainer in self.trainers:
                trainer.counters["update_credit"] -= 1
            for p, metrics in zip(passes, self.update(), strict=True):
                for k, v in metrics.items():
                    p.pending[k].append(v)

    def update(self) -> list[dict[str, float]]:
        """One update of every seed: its models, then its learner, each kind as one step."""
        trainers = self.trainers
        with timeit("update"):
            metrics: list[dict[str, float]] = [{} for _ in trainers]
            model_batches = [t.rewards.model_batches() for t in trainers]
            for name, step in self.models.items():
                losses = step(torch.stack([b[name] for b in model_batches])).tolist()
                for seed_metrics, loss in zip(metrics, losses, strict=True):
                    seed_metrics[f"model_{name}"] = loss
            for trainer in trainers:
                trainer.rewards.step(trainer.counters["updates"] + 1)
            batches = [t.rb.sample() for t in trainers]
            stacked, rescored = self.rescore(batches, trainers[0].cfg.learner.gamma)
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

    def _give_rows(self) -> None:
        """Each seed's own optimisers and target counter as a run of its own would hold them."""
        self.learner.optimizer_rows([t.learner.optimizer for t in self.trainers])
        for name, step in self.models.items():
            step.optimizer_rows([t.rewards.optimizers[name] for t in self.trainers])
        counter = self.learner.counter % self.learner.target_update_period
        for trainer in self.trainers:
            trainer.learner.target_updater.counter = counter


def train_seeds(
    cfgs: Sequence[TrainConfig], env_factory: EnvFactory | None = None
) -> list[dict[str, float]]:
    """Train the seeds of ``cfgs`` as one :class:`SeedGroup`; each seed's final evaluation."""
    return SeedGroup(cfgs, env_factory).run()
