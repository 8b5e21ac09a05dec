"""The one training loop shared by every recipe.

collect -> reward transforms -> buffers -> (model updates -> target copies / reward delay)
-> D4PG update -> target update -> log -> evaluate -> checkpoint.

Two replay buffers, both fed from every collected batch after the reward transforms: the
agent's prioritised buffer holds *n-step* transitions (``MultiStepTransform`` rewrites
``("next", obs)`` to s_{t+n} and sums every reward component), while the dynamics / penalty / ICM
models learn from *1-step* transitions (s_t, a_t, s_{t+1}, r^f_t), kept in a uniform buffer.
Updates start after ``init_random_frames``; each frame then earns ``utd_ratio`` updates.
"""

from __future__ import annotations

import random
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from tensordict import TensorDictBase
from torchrl.envs.transforms import MultiStepTransform
from tqdm.auto import tqdm

from gentlerl import keys
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.training.builders import (
    AGENT_KEYS,
    EnvFactory,
    check_env_keys,
    default_env_factory,
    make_buffers,
    make_collector,
    make_eval_env,
    make_exploration,
    make_learner,
    make_reward_stack,
)
from gentlerl.training.checkpoint import (
    load_checkpoint,
    load_replay_buffer_state,
    remove_stale_temp_files,
    replay_buffer_state,
    save_checkpoint,
)
from gentlerl.training.config import TrainConfig, validate
from gentlerl.training.evaluation import evaluate
from gentlerl.training.logging import EpisodeTracker, RunLogger

CHECKPOINT = "checkpoint.pt"
#: The actor of the best evaluation so far (see :meth:`Trainer._keep_best`); ``load_policy`` reads it.
BEST_POLICY = "best_policy.pt"
DONE_MARKER = "DONE"


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def _rng_state() -> dict[str, Any]:
    return {
        "python": random.getstate(),
        "numpy": np.random.get_state(),
        "torch": torch.get_rng_state(),
    }


def _set_rng_state(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])


class Trainer:
    """Holds a run's state; :meth:`run` executes (or resumes) it. See :func:`train`."""

    def __init__(self, cfg: TrainConfig, env_factory: EnvFactory | None = None) -> None:
        validate(cfg)
        self.cfg = cfg
        torch.set_num_threads(cfg.num_threads)
        seed_everything(cfg.seed)
        self.run_dir = Path(cfg.run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.env_factory = env_factory or default_env_factory(cfg)
        probe = self.env_factory()
        self.obs_dim = probe.observation_spec[keys.OBSERVATION].shape[-1]
        self.action_dim = probe.action_spec.shape[-1]
        self.max_steps = int(getattr(probe, "time_limit", 1000))
        self.stack = make_reward_stack(cfg, self.obs_dim, self.action_dim)
        check_env_keys(probe, self.stack)
        probe.close()
        self.learner = make_learner(cfg, self.obs_dim, self.action_dim)
        self.model_optims = {
            name: torch.optim.Adam(loss.parameters(), lr=cfg.lr_model)
            for name, loss in self.stack.model_losses.items()
        }
        self.total_updates = int(cfg.utd_ratio * max(cfg.total_frames - cfg.init_random_frames, 0))
        self.rb, self.beta_schedule, self.model_rb = make_buffers(cfg, self.total_updates)
        self.counters = {"frames": 0, "updates": 0, "update_credit": 0.0}
        self.nstep_tails: list[TensorDictBase | None] = []  # one per env (collector row)
        self.eval_history: list[dict[str, float]] = []
        self.best_eval: dict[str, float] | None = None

    # -- state ---------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        return {
            **self._policy_state(),
            "loss": self.learner.loss.state_dict(),
            "actor_optim": self.learner.actor_optim.state_dict(),
            "critic_optim": self.learner.critic_optim.state_dict(),
            "target_counter": self.learner.target_updater.counter,
            "stack": self.stack.state_dict(),
            "model_optims": {k: o.state_dict() for k, o in self.model_optims.items()},
            "rb": replay_buffer_state(self.rb),
            "nstep_tails": list(self.nstep_tails),
            "model_rb": replay_buffer_state(self.model_rb),
            "beta_schedule": self.beta_schedule.state_dict() if self.beta_schedule else None,
            "counters": dict(self.counters),
            "eval_history": list(self.eval_history),
            "best_eval": self.best_eval,
            "rng": _rng_state(),
        }

    def _policy_state(self) -> dict[str, Any]:
        """What :func:`~gentlerl.training.checkpoint.load_policy` reads: config, sizes, actor."""
        return {
            "config": self.cfg.to_dict(),
            "obs_dim": self.obs_dim,
            "action_dim": self.action_dim,
            "actor": self.learner.actor.state_dict(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.learner.loss.load_state_dict(state["loss"])
        self.learner.actor_optim.load_state_dict(state["actor_optim"])
        self.learner.critic_optim.load_state_dict(state["critic_optim"])
        self.learner.target_updater.counter = state["target_counter"]
        self.stack.load_state_dict(state["stack"])
        for k, o in self.model_optims.items():
            o.load_state_dict(state["model_optims"][k])
        load_replay_buffer_state(self.rb, state["rb"])
        self.nstep_tails = [_cut(tail) for tail in state["nstep_tails"]]
        load_replay_buffer_state(self.model_rb, state["model_rb"])
        if self.beta_schedule is not None:
            self.beta_schedule.load_state_dict(state["beta_schedule"])
        self.counters = dict(state["counters"])
        self.eval_history = list(state["eval_history"])
        self.best_eval = state.get("best_eval")  # absent in checkpoints from before it existed
        _set_rng_state(state["rng"])

    def _extend_agent_buffer(self, batch: TensorDictBase) -> None:
        """Write each env's time row through the n-step transform with that env's pending tail.

        ``MultiStepTransform`` keeps one tail of pending steps and the storage is flat, so a
        ``[num_workers, T]`` batch is written row by row, swapping the tails.
        """
        nstep = next(t for t in self.rb.transform if isinstance(t, MultiStepTransform))
        rows = batch.unbind(0) if batch.ndim == 2 else (batch,)
        if len(self.nstep_tails) != len(rows):
            self.nstep_tails = [None] * len(rows)
        for i, row in enumerate(rows):
            nstep._buffer = self.nstep_tails[i]
            self.rb.extend(row)
            self.nstep_tails[i] = nstep._buffer

    def save(self) -> None:
        save_checkpoint(self.run_dir / CHECKPOINT, self.state_dict())

    # -- updates -------------------------------------------------------------------------
    def _update_models(self) -> dict[str, float]:
        metrics = {}
        b = self.cfg.model_batch_size
        for name, loss in self.stack.model_losses.items():
            if isinstance(loss, EnsembleModelLoss):
                e = loss.ensemble_size
                batch = self.model_rb.sample(e * b).reshape(e, b)  # a bootstrap batch per member
            else:
                batch = self.model_rb.sample(b)
            out = loss(batch)
            total = sum(v for k, v in out.items() if k.startswith("loss_"))
            self.model_optims[name].zero_grad()
            total.backward()
            self.model_optims[name].step()
            metrics[f"model_{name}"] = total.item()
        self.stack.step(self.counters["updates"] + 1)
        return metrics

    def _update_learner(self) -> dict[str, float]:
        learner = self.learner
        batch = self.rb.sample()
        out = learner.loss(batch)
        learner.actor_optim.zero_grad()
        learner.critic_optim.zero_grad()
        (out["loss_value"] + out["loss_actor"]).backward()  # disjoint parameters
        learner.critic_optim.step()
        learner.actor_optim.step()
        learner.target_updater.step()
        self.rb.update_tensordict_priority(batch)
        if self.beta_schedule is not None:
            self.beta_schedule.step()
        metrics = {k: v.item() for k, v in out.items()}
        for key in self.cfg.reward_keys:
            metrics[f"batch_{key}"] = batch.get(("next", key)).mean().item()
        return metrics

    # -- the loop ------------------------------------------------------------------------
    def run(self) -> dict[str, float]:
        cfg = self.cfg
        ckpt = self.run_dir / CHECKPOINT
        remove_stale_temp_files(self.run_dir)
        if cfg.resume and ckpt.exists():
            self.load_state_dict(load_checkpoint(ckpt))
        elif not cfg.resume and (ckpt.exists() or (self.run_dir / "logs").exists()):
            raise ValueError(
                f"run_dir={str(self.run_dir)!r} already holds a run; pass resume=true to continue "
                "it, or choose another run_dir"
            )
        (self.run_dir / "config.yaml").write_text(yaml.safe_dump(_plain(cfg.to_dict())))
        logger = RunLogger(self.run_dir, _plain(cfg.to_dict()), cfg.wandb_mode, cfg.wandb_project)
        logger.truncate_after(self.counters["frames"])
        tracker = EpisodeTracker(cfg.reward_keys)
        eval_env = make_eval_env(self.env_factory, cfg.seed + 10_000, cfg.eval_episodes)
        frames_left = cfg.total_frames - self.counters["frames"]
        if frames_left > 0:
            self._collect(frames_left, logger, tracker, eval_env)
        summary = self._evaluate(logger, eval_env)
        self.save()
        (self.run_dir / DONE_MARKER).write_text("done\n")
        logger.close()
        eval_env.close()
        return summary

    def _collect(
        self, frames_left: int, logger: RunLogger, tracker: EpisodeTracker, eval_env: Any
    ) -> None:
        cfg, c = self.cfg, self.counters
        policy = make_exploration(self.learner, cfg, self.action_dim)
        random_left = max(cfg.init_random_frames - c["frames"], 0)
        seed = cfg.seed + c["frames"]
        collector = make_collector(cfg, self.env_factory, policy, frames_left, random_left, seed)
        collector.set_seed(seed)
        pending: dict[str, list[float]] = defaultdict(list)
        recent: list[dict[str, float]] = []
        next_eval = (c["frames"] // cfg.eval_every_frames + 1) * cfg.eval_every_frames
        next_ckpt = (c["frames"] // cfg.checkpoint_every_frames + 1) * cfg.checkpoint_every_frames
        bar = tqdm(
            total=cfg.total_frames, initial=c["frames"], disable=not cfg.progress, unit="frame"
        )
        start, start_frames = time.perf_counter(), c["frames"]
        update_time = 0.0
        for batch in collector:
            batch = self.stack.transform(batch)
            c["frames"] += batch.numel()
            for ep in tracker.update(batch):
                logger.log({f"episode/{k}": v for k, v in ep.items()}, c["frames"])
                recent = (recent + [ep])[-20:]
            self.model_rb.extend(
                batch.exclude(keys.TOUCH_GRID, ("next", keys.TOUCH_GRID), "collector").reshape(-1)
            )
            self._extend_agent_buffer(
                batch.select(*AGENT_KEYS, *[("next", k) for k in cfg.reward_keys])
            )
            if c["frames"] > cfg.init_random_frames and len(self.rb) >= cfg.batch_size:
                c["update_credit"] += cfg.utd_ratio * batch.numel()
                update_start = time.perf_counter()
                while c["update_credit"] >= 1:
                    c["update_credit"] -= 1
                    if self.stack.model_losses:
                        for k, v in self._update_models().items():
                            pending[k].append(v)
                    for k, v in self._update_learner().items():
                        pending[k].append(v)
                    c["updates"] += 1
                update_time += time.perf_counter() - update_start
                if cfg.collector == "multi":
                    collector.update_policy_weights_()
            elapsed = time.perf_counter() - start
            if pending and len(pending["loss_value"]) >= cfg.log_every_updates:
                scalars = {f"train/{k}": float(np.mean(v)) for k, v in pending.items()}
                scalars["train/intrinsic_on"] = float(self.stack.intrinsic_on)
                # Model + learner updates per second of update time (collection excluded).
                scalars["train/updates_per_s"] = len(pending["loss_value"]) / max(update_time, 1e-9)
                logger.log(scalars, c["frames"])
                pending.clear()
                update_time = 0.0
            fps = (c["frames"] - start_frames) / max(elapsed, 1e-9)
            logger.log({"train/env_steps_per_s": fps}, c["frames"])
            if c["frames"] >= next_eval:
                self._evaluate(logger, eval_env)
                next_eval += cfg.eval_every_frames
            if c["frames"] >= next_ckpt:
                self.save()
                next_ckpt += cfg.checkpoint_every_frames
            bar.update(batch.numel())
            bar.set_postfix(
                fps=f"{fps:.0f}",
                success=f"{np.mean([e['success'] for e in recent]) if recent else 0:.2f}",
                max_impact=f"{np.mean([e['max_impact'] for e in recent]) if recent else 0:.2f}N",
                eval=f"{self.eval_history[-1]['success_rate']:.2f}" if self.eval_history else "-",
            )
        bar.close()
        collector.shutdown()

    def _evaluate(self, logger: RunLogger, eval_env: Any) -> dict[str, float]:
        summary, episodes = evaluate(
            eval_env, self.learner.actor, self.cfg.eval_episodes, self.max_steps
        )
        frames = self.counters["frames"]
        logger.log({f"eval/{k}": v for k, v in summary.items()}, frames)
        logger.log_eval_episodes(frames, episodes)
        self.eval_history.append({"frames": frames, **summary})
        self._keep_best({"frames": frames, **summary})
        return summary

    def _keep_best(self, result: dict[str, float]) -> None:
        """Save the actor to :data:`BEST_POLICY` when this evaluation beats every earlier one.

        Order: higher success rate, then lower broken rate, then lower mean max impact (the
        gentler of two equally successful policies). DDPG policies can lose a solved task later
        in training (docs/REPRODUCTION.md), so the best one is kept apart from the last one.
        """

        def rank(r: dict[str, float]) -> tuple[float, float, float]:
            return (r["success_rate"], -r["broken_rate"], -r["max_impact_mean"])

        if self.best_eval is not None and rank(result) <= rank(self.best_eval):
            return
        self.best_eval = dict(result)
        save_checkpoint(
            self.run_dir / BEST_POLICY, {**self._policy_state(), "eval": self.best_eval}
        )


def _cut(tail: TensorDictBase | None) -> TensorDictBase | None:
    """Mark the last pending step of each n-step window as truncated.

    The resumed collector starts new episodes, so the episodes running at checkpoint time end
    there: their pending transitions are written with windows cut at that step (bootstrapping
    from it, as a time limit would), none lost and none summed across the cut.
    """
    if tail is None:
        return None
    tail = tail.clone()
    for key in (keys.DONE, keys.TRUNCATED):
        tail.get(("next", key))[..., -1, :] = True
    return tail


def _plain(value: Any) -> Any:
    """Tuples to lists so the config dumps as plain YAML."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def train(cfg: TrainConfig, env_factory: EnvFactory | None = None) -> dict[str, float]:
    """Train (or, with ``cfg.resume``, continue) a run; returns the final evaluation summary.

    ``env_factory`` builds the env (default: :func:`gentlerl.envs.make_env` for ``cfg.task``); it
    must write ``observation``, ``success`` and ``broken`` and the force key of ``ImpactPenalty``.
    """
    return Trainer(cfg, env_factory).run()
