"""What a runner builds (TorchRL sota-implementations style): the process set-up, the agent
(from a probed env), the collector, the evaluation env and the logger.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from functools import partial
from typing import Any, NamedTuple

import torch
from torchrl.collectors import BaseCollector, Collector, MultiSyncCollector
from torchrl.data import ReplayBuffer
from torchrl.data.replay_buffers.scheduler import LinearScheduler
from torchrl.envs import EnvBase, TransformedEnv

from gentlerl import keys
from gentlerl.agent.builder import AgentBuilder
from gentlerl.config import CollectorConfig
from gentlerl.config.groups import AUTO_NUM_ENVS
from gentlerl.config.layout import RunLayout
from gentlerl.data import NStepWriter
from gentlerl.files import dump_yaml, write_atomic
from gentlerl.lazy import record_missing_pandas
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.rewards import IntrinsicRewards
from gentlerl.training import resume
from gentlerl.training.config import TrainConfig
from gentlerl.training.evaluation import EVAL_SEED_OFFSET, make_eval_env, takes_num_envs
from gentlerl.training.logging import RunLogger, episode_transforms
from gentlerl.training.prefetch import PrefetchCollector
from gentlerl.training.process_collector import ProcessCollector
from gentlerl.training.seeding import seed_everything

EnvFactory = Callable[..., EnvBase]
#: A run's collector: TorchRL's (one process, several, Ray actors), or one a batch ahead.
RunCollector = BaseCollector | PrefetchCollector | ProcessCollector

#: Keys the agent's n-step buffer keeps (plus the reward components under "next").
AGENT_KEYS = (
    keys.OBSERVATION,
    keys.ACTION,
    ("next", keys.OBSERVATION),
    ("next", keys.DONE),
    ("next", keys.TERMINATED),
    ("next", keys.TRUNCATED),
)


def default_env_factory(cfg: TrainConfig) -> EnvFactory:
    """``gentlerl.envs.make_env`` for ``cfg.task`` with ``cfg.env.kwargs``, seeded with ``cfg.seed``;
    with ``cfg.env.name`` the external env it names
    (:func:`~gentlerl.envs.external.make_external_env`, ``env.kwargs`` to its constructor)."""
    if cfg.env.name is not None:
        from gentlerl.envs.external import make_external_env

        env = cfg.env
        return partial(
            make_external_env,
            env.name,
            seed=cfg.seed,
            force_adapter=env.force_adapter,
            force_key=env.force,
            observation_keys=env.observation_keys,
            force_scale=env.force_scale,
            force_groups=env.force_groups or None,
            **env.kwargs,
        )
    from gentlerl.envs import make_env

    return partial(make_env, cfg.task, seed=cfg.seed, **cfg.env.kwargs)


def prepare_process(cfg: TrainConfig) -> None:
    """This process's side of a run: torch's threads, a missing pandas recorded
    (:func:`record_missing_pandas`) and every global seed."""
    torch.set_num_threads(cfg.num_threads)
    record_missing_pandas()
    seed_everything(cfg.seed)


def _seeded_env(env_factory: EnvFactory, seed: int) -> EnvBase:
    """``env_factory()`` seeded before anything resets it (collectors reset the env they build),
    with the :func:`~gentlerl.training.logging.episode_transforms` the episode statistics read."""
    env = env_factory()
    env.set_seed(seed)
    env = TransformedEnv(env)
    for transform in episode_transforms():
        env.append_transform(transform)
    return env


def collection_env_factory(cfg: CollectorConfig, env_factory: EnvFactory) -> EnvFactory:
    """``env_factory`` for the collector: ``cfg.num_envs`` hands per env when above 1 (null:
    :data:`~gentlerl.config.groups.AUTO_NUM_ENVS` for the single collector where the factory
    batches and they divide ``frames_per_batch``, else 1)."""
    num_envs = cfg.num_envs
    if num_envs is None:
        auto = (
            cfg.kind == "single"
            and takes_num_envs(env_factory)
            and cfg.frames_per_batch % AUTO_NUM_ENVS == 0
        )
        num_envs = AUTO_NUM_ENVS if auto else 1
    if num_envs == 1:
        return env_factory
    if not takes_num_envs(env_factory):
        raise ValueError(
            f"num_envs={num_envs} needs an env factory that takes num_envs (as "
            "gentlerl.envs.make_env does); this one does not"
        )
    from gentlerl.envs.batched import available_cores  # the envs load dm_control: only here

    threads = cfg.env_threads
    if threads is not None and threads > available_cores():
        warnings.warn(
            f"collector.env_threads={threads} is more than the {available_cores()} CPU cores "
            f"available; using {available_cores()}",
            stacklevel=2,
        )
        threads = available_cores()
    return partial(env_factory, num_envs=num_envs, num_threads=threads)


class AgentParts(NamedTuple):
    """What a run trains, as :func:`make_agent` builds it (the D4PG loss without its
    :class:`~gentlerl.agent.Learner`: that is made once for the seeds that train together)."""

    builder: AgentBuilder
    rewards: IntrinsicRewards
    loss: MultiHeadD4PGLoss
    writer: NStepWriter
    rb: ReplayBuffer
    beta_schedule: LinearScheduler | None


def make_agent(
    cfg: TrainConfig, env_factory: EnvFactory, probe: EnvBase | None = None
) -> AgentParts:
    """The agent of ``cfg``, sized from the env ``probe`` (closed here; default: one of
    ``env_factory``), which must write what the reward transforms read (the builder checks it);
    the beta schedule spans the run's ``utd_ratio`` updates."""
    probe = probe if probe is not None else env_factory()
    try:
        builder = AgentBuilder(cfg, probe)
    finally:
        probe.close()
    loss = builder.make_loss()
    col = cfg.collector
    updates = int(cfg.learner.utd_ratio * max(col.total_frames - col.init_random_frames, 0))
    writer, rb, beta_schedule = builder.make_replay(updates, builder.rewards.window_keys)
    return AgentParts(builder, builder.rewards, loss, writer, rb, beta_schedule)


def make_collector(
    cfg: CollectorConfig,
    env_factory: EnvFactory,
    policy: torch.nn.Module,
    frames_left: int,
    random_left: int,
    seed: int,
) -> RunCollector:
    """TorchRL ``Collector`` (one process), ``MultiSyncCollector`` (``num_workers`` processes) or
    ``RayCollector`` (``num_workers`` Ray actors, :mod:`gentlerl.distributed.collector`); with
    ``cfg.overlap`` the single collector runs one batch ahead, on a thread (``true``:
    :class:`~gentlerl.training.prefetch.PrefetchCollector`) or in a child process
    (``"process"``: :class:`~gentlerl.training.process_collector.ProcessCollector`).

    Worker ``i``'s env is seeded with ``seed + i`` before the collector's first reset (the first
    block position too; ``collector.set_seed`` comes too late for it). Env, policy and batch share
    the policy's device, so that TorchRL casts nothing at each step.

    The multi-process collector is the *synchronous* one: it stacks the workers' batches into
    ``[num_workers, T]``, so each row stays time-contiguous across batches (what the n-step
    writer needs), and runs are reproducible with a seed.
    ``MultiAsyncCollector`` interleaves workers' batches in arrival order, which breaks both.
    """
    common = dict(
        frames_per_batch=cfg.frames_per_batch,
        total_frames=frames_left,
        init_random_frames=random_left,
        auto_register_policy_transforms=False,  # a stateless policy: no InitTracker / primer
        device=next((p.device for p in policy.parameters()), None),  # no per-step casts
    )
    env_factory = collection_env_factory(cfg, env_factory)
    if cfg.kind == "single" and cfg.overlap:
        build = partial(Collector, partial(_seeded_env, env_factory, seed), **common)
        ahead = ProcessCollector if cfg.overlap == "process" else PrefetchCollector
        return ahead(build, policy, seed)
    if cfg.kind == "single":
        return Collector(partial(_seeded_env, env_factory, seed), policy, **common)
    factories = [partial(_seeded_env, env_factory, seed + i) for i in range(cfg.num_workers)]
    if cfg.kind == "ray":
        from gentlerl.distributed.collector import make_ray_collector

        return make_ray_collector(
            factories, policy, frames_per_batch=cfg.frames_per_batch, total_frames=frames_left,
            init_random_frames=random_left, address=cfg.ray_address,
            cpus_per_worker=cfg.cpus_per_worker, memory_per_worker_gb=cfg.memory_per_worker_gb,
        )  # fmt: skip
    return MultiSyncCollector(factories, policy, cat_results="stack", **common)


def make_run_collector(
    cfg: TrainConfig, env_factory: EnvFactory, policy: torch.nn.Module, frames: int
) -> RunCollector:
    """:func:`make_collector` for the rest of a run that has collected ``frames``: seeded with
    ``cfg.seed + frames``, Ray workers starting from ``policy``'s current weights."""
    col, seed = cfg.collector, cfg.seed + frames
    random_left = max(col.init_random_frames - frames, 0)
    collector = make_collector(
        col, env_factory, policy, col.total_frames - frames, random_left, seed
    )
    try:
        collector.set_seed(seed)
        if col.kind == "ray":
            collector.update_policy_weights_()
    except BaseException:
        collector.shutdown()
        raise
    return collector


def make_run_eval_env(cfg: TrainConfig, env_factory: EnvFactory) -> EnvBase:
    """The run's :func:`make_eval_env`: ``logging.eval_episodes`` hands seeded with
    ``cfg.seed + EVAL_SEED_OFFSET``."""
    seed = cfg.seed + EVAL_SEED_OFFSET
    return make_eval_env(env_factory, seed, cfg.logging.eval_episodes, cfg.env.force)


def write_config(cfg: TrainConfig, layout: RunLayout) -> dict[str, Any]:
    """Write the run's full config to ``layout.config``; returns it as plain YAML data."""
    config = resume.plain(cfg.to_dict())
    write_atomic(layout.config, dump_yaml(config))
    return config


def make_logger(cfg: TrainConfig, config: dict[str, Any]) -> RunLogger:
    """The run's :class:`~gentlerl.training.logging.RunLogger` (``config`` goes to wandb)."""
    log = cfg.logging
    return RunLogger(cfg.run_dir, config, log.wandb_mode, log.wandb_project, log.logger)
