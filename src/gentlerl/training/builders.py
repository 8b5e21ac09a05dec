"""Wiring helpers (TorchRL sota-implementations style): env, collector, learner, buffers."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import torch
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.objectives import HardUpdate

from gentlerl import keys
from gentlerl.data import make_beta_scheduler, make_model_buffer, make_replay_buffer
from gentlerl.models import make_actor, make_critic, make_exploration_policy
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.training.config import TrainConfig
from gentlerl.training.prefetch import PrefetchCollector
from gentlerl.transforms import ImpactPenalty, RewardStack, make_reward_transforms

EnvFactory = Callable[..., EnvBase]

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
    """``gentlerl.envs.make_env`` for ``cfg.task`` with ``cfg.env_kwargs``, seeded with ``cfg.seed``."""
    from gentlerl.envs import make_env

    return partial(make_env, cfg.task, seed=cfg.seed, **cfg.env_kwargs)


def _seeded_env(env_factory: EnvFactory, seed: int) -> EnvBase:
    """``env_factory()`` seeded before anything resets it (collectors reset the env they build)."""
    env = env_factory()
    env.set_seed(seed)
    return env


def takes_num_envs(env_factory: EnvFactory) -> bool:
    """Whether ``env_factory`` builds batched envs (it takes ``num_envs``, as ``make_env``)."""
    try:
        params = inspect.signature(env_factory).parameters.values()
    except (TypeError, ValueError):  # builtins / C callables: no signature to read
        return False
    return any(p.name == "num_envs" for p in params)


def collection_env_factory(cfg: TrainConfig, env_factory: EnvFactory) -> EnvFactory:
    """``env_factory`` for the collector: ``cfg.num_envs`` hands per env when above 1."""
    if cfg.num_envs == 1:
        return env_factory
    if not takes_num_envs(env_factory):
        raise ValueError(
            f"num_envs={cfg.num_envs} needs an env factory that takes num_envs (as "
            "gentlerl.envs.make_env does); this one does not"
        )
    return partial(env_factory, num_envs=cfg.num_envs, num_threads=cfg.env_threads)


#: What the loop reads from every env step besides the variant's reward components.
REQUIRED_ENV_KEYS = (keys.OBSERVATION, keys.SUCCESS, keys.BROKEN)


def check_env_keys(env: EnvBase, stack: RewardStack) -> None:
    """One clear error if env + reward transforms do not produce what the run reads.

    That is :data:`REQUIRED_ENV_KEYS`, ``impact`` (``ImpactPenalty``, logged for every variant)
    and every reward component of the variant.
    """
    try:
        transformed = TransformedEnv(env, stack.transform.clone(), auto_unwrap=False)
        produced = set(transformed.full_reward_spec.keys(True, True)) | set(
            transformed.full_observation_spec.keys(True, True)
        )
    except KeyError as err:
        raise ValueError(
            f"the env does not produce {err} that the reward transforms read "
            f"(env observation keys: {sorted(map(str, env.full_observation_spec.keys(True, True)))})"
        ) from err
    wanted = [*REQUIRED_ENV_KEYS, keys.IMPACT, *stack.reward_keys]
    missing = [k for k in wanted if k not in produced]
    if missing:
        raise ValueError(
            f"key(s) {missing} needed by the run are produced neither by the env nor by the "
            f"reward transforms (produced: {sorted(map(str, produced))})"
        )


def make_reward_stack(cfg: TrainConfig, obs_dim: int, action_dim: int) -> RewardStack:
    return make_reward_transforms(
        cfg.variant,
        obs_dim=obs_dim,
        action_dim=action_dim,
        lam=cfg.lam,
        lam_prime=cfg.lam_prime,
        reward_delay=cfg.reward_delay,
        dynamics_target_period=cfg.dynamics_target_period,
        penalty_target_period=cfg.penalty_target_period,
        ensemble_size=cfg.ensemble_size,
        hidden=cfg.model_hidden,
        surprise_scale=cfg.surprise_scale,
        surprise_nll_floor=cfg.surprise_nll_floor,
        icm_eta=cfg.icm_eta,
        seed=cfg.seed,
    )


@dataclass
class Learner:
    """The D4PG actor-critic, its optimisers and target updater."""

    loss: MultiHeadD4PGLoss
    actor_optim: torch.optim.Optimizer
    critic_optim: torch.optim.Optimizer
    target_updater: HardUpdate

    @property
    def actor(self) -> torch.nn.Module:
        return self.loss.actor_network


def make_learner(cfg: TrainConfig, obs_dim: int, action_dim: int) -> Learner:
    actor = make_actor(obs_dim, action_dim, cfg.actor_hidden)
    critic = make_critic(
        obs_dim, action_dim, len(cfg.reward_keys), cfg.critic_hidden, cfg.num_atoms
    )
    loss = MultiHeadD4PGLoss(
        actor,
        critic,
        reward_keys=cfg.reward_keys,
        non_episodic_keys=[] if cfg.episodic_intrinsic else _intrinsic(cfg.reward_keys),
        v_min=cfg.v_min,
        v_max=[_head_v_max(cfg, k) for k in cfg.reward_keys],
        gamma=cfg.gamma,
        policy_noise=cfg.policy_noise,
    )
    loss.set_keys(terminated=keys.NSTEP_TERMINATED)
    return Learner(
        loss=loss,
        actor_optim=torch.optim.Adam(loss.actor_network_params.values(True, True), lr=cfg.lr_actor),
        critic_optim=torch.optim.Adam(
            loss.value_network_params.values(True, True), lr=cfg.lr_critic
        ),
        # TorchRL's HardUpdate copies on the (interval + 1)-th step (Acme: every 100 updates).
        target_updater=HardUpdate(loss, value_network_update_interval=cfg.target_update_period - 1),
    )


def make_buffers(cfg: TrainConfig, total_updates: int) -> tuple:
    """The agent's prioritised n-step buffer, its beta schedule, and the models' 1-step buffer."""
    rb = make_replay_buffer(
        cfg.buffer_size,
        cfg.batch_size,
        prioritized=cfg.prioritized,
        alpha=cfg.alpha,
        beta=cfg.beta,
        n_steps=cfg.n_steps,
        gamma=cfg.gamma,
        reward_keys=cfg.reward_keys,
    )
    beta_schedule = make_beta_scheduler(rb, 1.0, max(total_updates, 1)) if cfg.prioritized else None
    model_rb = make_model_buffer(cfg.model_buffer_size)
    return rb, beta_schedule, model_rb


def make_collector(
    cfg: TrainConfig,
    env_factory: EnvFactory,
    policy: torch.nn.Module,
    frames_left: int,
    random_left: int,
    seed: int,
) -> Collector | MultiSyncCollector | PrefetchCollector:
    """TorchRL ``Collector`` (one process) or ``MultiSyncCollector`` (``num_workers`` processes);
    with ``cfg.overlap`` the single collector runs one batch ahead on a thread
    (:class:`~gentlerl.training.prefetch.PrefetchCollector`).

    Worker ``i``'s env is seeded with ``seed + i`` before the collector's first reset, so the
    first episode (its block position) is reproducible too; ``collector.set_seed`` comes too late
    for it.

    The multi-process collector is the *synchronous* one: it stacks the workers' batches into
    ``[num_workers, T]``, so each row stays time-contiguous across batches (what the n-step
    transform of the replay buffer needs), and runs are reproducible with a seed.
    ``MultiAsyncCollector`` interleaves workers' batches in arrival order, which breaks both.
    """
    common = dict(
        frames_per_batch=cfg.frames_per_batch,
        total_frames=frames_left,
        init_random_frames=random_left,
        # The policy is stateless: the env needs no InitTracker / primer (and no FutureWarning).
        auto_register_policy_transforms=False,
    )
    env_factory = collection_env_factory(cfg, env_factory)
    if cfg.collector == "single" and cfg.overlap:
        seeded = partial(_seeded_env, env_factory, seed)
        return PrefetchCollector(lambda p: Collector(seeded, p, **common), policy, seed)
    if cfg.collector == "single":
        return Collector(partial(_seeded_env, env_factory, seed), policy, **common)
    factories = [partial(_seeded_env, env_factory, seed + i) for i in range(cfg.num_workers)]
    return MultiSyncCollector(factories, policy, cat_results="stack", **common)


def _head_v_max(cfg: TrainConfig, reward_key: str) -> float:
    if reward_key == keys.PENALTY and cfg.penalty_v_max is not None:
        return cfg.penalty_v_max
    return cfg.v_max


def _intrinsic(reward_keys: list[str]) -> list[str]:
    return [k for k in reward_keys if k in keys.INTRINSIC_REWARDS]


def make_exploration(learner: Learner, cfg: TrainConfig, action_dim: int) -> torch.nn.Module:
    return make_exploration_policy(learner.actor, cfg.sigma, action_dim=action_dim)


def make_eval_env(env_factory: EnvFactory, seed: int, episodes: int = 1) -> EnvBase:
    """The evaluation env (writes ``impact``): ``episodes`` hands stepped together where the
    factory builds batched envs (all episodes of an evaluation in one rollout), else one."""
    batched = episodes > 1 and takes_num_envs(env_factory)
    env = TransformedEnv(
        env_factory(num_envs=episodes) if batched else env_factory(), ImpactPenalty()
    )
    env.set_seed(seed)
    return env
