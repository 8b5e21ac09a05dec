"""``AgentBuilder``: the agent's parts for a config and an env (Acme's D4PG builder).

A runner (one process, a multi-process collector, later a distributed one) asks the builder for
the policy it acts with, the learner it updates and the reward transform it applies; it never
builds networks itself, so every runner trains the same agent.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import torch
from tensordict.utils import NestedKey
from torchrl.data import ReplayBuffer
from torchrl.data.replay_buffers.scheduler import LinearScheduler
from torchrl.envs import EnvBase

from gentlerl import keys
from gentlerl.agent.learner import Learner
from gentlerl.config import (
    CollectorConfig,
    EnvConfig,
    GentlenessConfig,
    LearnerConfig,
    NetworkConfig,
    ReplayConfig,
)
from gentlerl.data import NStepWriter, make_beta_scheduler, make_replay_buffer
from gentlerl.deprecation import moved_method
from gentlerl.models import make_actor, make_critic, make_exploration_policy
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.rewards.env_sizes import check_env_keys, env_feature_shapes, episode_steps
from gentlerl.rewards.intrinsic import IntrinsicRewards
from gentlerl.rewards.variants import (
    critic_supports,
    derived_support,
    derives_support,
    discounted_horizon,
    intrinsic_keys,
    reward_keys,
    task_reward_bounds,
)


def configured_learner(
    losses: MultiHeadD4PGLoss | Sequence[MultiHeadD4PGLoss], settings: LearnerConfig
) -> Learner:
    """A :class:`Learner` over ``losses`` (one seed's, or several seeds' as one step) with the
    step sizes, target period and launch of ``settings``: the one place a run reads them."""
    return Learner(
        losses,
        lr_actor=settings.lr_actor,
        lr_critic=settings.lr_critic,
        target_update_period=settings.target_update_period,
        compile=settings.compile,
        cudagraphs=settings.cudagraphs,
    )


class AgentConfig(Protocol):
    """What the builder reads of a run's config (:class:`gentlerl.training.TrainConfig` is one):
    the variant, the seed and the groups of :mod:`gentlerl.config`."""

    variant: str
    seed: int
    env: EnvConfig
    collector: CollectorConfig
    replay: ReplayConfig
    learner: LearnerConfig
    network: NetworkConfig
    gentleness: GentlenessConfig


class AgentBuilder:
    """Makes the agent of ``cfg`` for ``env``, whose specs give every size.

    Attributes:
        obs_dim, action_dim: sizes of ``observation`` and ``action``.
        feature_shapes: shape of each of the dynamics model's feature groups that the env
            writes: the hand's joint positions, velocities and touch; else the entries an
            external env's ``observation`` concatenates (finger: position, velocity, touch).
        reward_keys: the variant's reward components, in critic-head order.
        supports: each critic head's ``(v_min, v_max)`` (:func:`~gentlerl.rewards.variants.critic_supports`).
        rewards: the variant's :class:`~gentlerl.rewards.IntrinsicRewards`.
    """

    #: Deprecated (removed in 0.3.0): the attribute :attr:`rewards`.
    make_intrinsic_rewards = moved_method("make_intrinsic_rewards", "rewards", attribute=True)

    def __init__(self, cfg: AgentConfig, env: EnvBase) -> None:
        self.cfg = cfg
        self.obs_dim = env.observation_spec[keys.OBSERVATION].shape[-1]
        self.action_dim = env.action_spec.shape[-1]
        #: Steps per episode (the env's ``time_limit``, else 1000): the dense heads' horizon.
        self.horizon = episode_steps(env)
        self.feature_shapes = env_feature_shapes(env)
        self.reward_keys = reward_keys(cfg.variant)
        self.intrinsic_keys = intrinsic_keys(self.reward_keys)
        horizon = discounted_horizon(cfg.learner.gamma, self.horizon)
        #: The task head's derived ``(v_min, v_max)``, or ``None``: ``network.v_min/v_max``.
        self.task_support = (
            derived_support(task_reward_bounds(cfg.env), horizon)
            if derives_support(cfg.env, cfg.network)
            else None
        )
        self.supports = critic_supports(self.reward_keys, cfg.network, horizon, self.task_support)
        #: The variant's reward transforms and their models (on ``learner.device``, launched as
        #: the learner's update is), checked against ``env``: it must write what they read.
        self.rewards = IntrinsicRewards(
            cfg.variant,
            cfg.gentleness,
            obs_dim=self.obs_dim,
            action_dim=self.action_dim,
            feature_shapes=self.feature_shapes,
            seed=cfg.seed,
            force_key=cfg.env.force,
            device=cfg.learner.device,
            compile=cfg.learner.compile,
            cudagraphs=cfg.learner.cudagraphs,
        )
        check_env_keys(env, self.rewards.transform, self.reward_keys)

    def make_learner(self) -> Learner:
        """A :class:`Learner` of one seed over :meth:`make_loss` (``learner``'s settings)."""
        return configured_learner(self.make_loss(), self.cfg.learner)

    def make_loss(self) -> MultiHeadD4PGLoss:
        """A new actor and critic (drawn from torch's generator) in the variant's multi-head
        D4PG loss, on ``learner.device``, its head weights those the rewards start with."""
        net, learner = self.cfg.network, self.cfg.learner
        actor = make_actor(self.obs_dim, self.action_dim, net.actor_hidden)
        v_min, v_max = self.supports
        critic = make_critic(
            self.obs_dim,
            self.action_dim,
            len(self.reward_keys),
            net.critic_hidden,
            net.num_atoms,
            v_min=v_min,
            v_max=v_max,
        )
        loss = MultiHeadD4PGLoss(
            actor,
            critic,
            reward_keys=self.reward_keys,
            non_episodic_keys=[] if learner.episodic_intrinsic else self.intrinsic_keys,
            policy_noise=learner.policy_noise,
            normalize_values=learner.normalize_values,
        )
        loss.make_value_estimator(gamma=learner.gamma)
        loss.set_keys(terminated=keys.NSTEP_TERMINATED)
        for key, weight in self.rewards.head_weights().items():  # until the first PID step
            loss.set_head_weight(key, weight)
        return loss.to(learner.device)

    def make_policy(self, learner: Learner, seed: int = 0) -> torch.nn.Module:
        """The learner's acting actor of seed ``seed`` (:meth:`Learner.policy_of`, on the CPU)
        with Gaussian exploration noise (``collector.sigma``)."""
        return make_exploration_policy(
            learner.policy_of(seed), self.cfg.collector.sigma, action_dim=self.action_dim
        )

    def make_replay(
        self, total_updates: int, window_keys: Sequence[NestedKey] = ()
    ) -> tuple[NStepWriter, ReplayBuffer, LinearScheduler | None]:
        """The agent's prioritised buffer, its n-step writer and its beta schedule.

        ``window_keys``: entries kept per window step (:attr:`IntrinsicRewards.window_keys`).
        """
        replay = self.cfg.replay
        rb = make_replay_buffer(
            replay.buffer_size,
            replay.batch_size,
            prioritized=replay.prioritized,
            alpha=replay.alpha,
            beta=replay.beta,
            n_steps=None,
            device=self.cfg.learner.device if replay.device == "learner" else "cpu",
        )
        writer = NStepWriter(
            rb, replay.n_steps, self.cfg.learner.gamma, self.reward_keys, window_keys
        )
        schedule = (
            make_beta_scheduler(rb, 1.0, max(total_updates, 1)) if replay.prioritized else None
        )
        return writer, rb, schedule
