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
from gentlerl.models import make_actor, make_critic, make_exploration_policy
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.rewards.intrinsic import IntrinsicRewards
from gentlerl.rewards.specs import env_feature_shapes
from gentlerl.rewards.variants import (
    discounted_horizon,
    head_supports,
    intrinsic_keys,
    reward_keys,
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


def episode_steps(env: EnvBase, default: int = 1000) -> int:
    """``env.time_limit`` (control steps per episode) where the env names one, else ``default``.

    Read without ``getattr`` on the env: a batched TorchRL env forwards unknown attributes to its
    workers, which recurses before they start.
    """
    limit = vars(env).get("time_limit")
    if limit is None and isinstance(getattr(type(env), "time_limit", None), property):
        limit = env.time_limit
    return default if limit is None else int(limit)


class AgentBuilder:
    """Makes the agent of ``cfg`` for ``env``, whose specs give every size.

    Attributes:
        obs_dim, action_dim: sizes of ``observation`` and ``action``.
        feature_shapes: shape of each of the dynamics model's feature groups that the env
            writes: the hand's joint positions, velocities and touch; else the entries an
            external env's ``observation`` concatenates (finger: position, velocity, touch).
        reward_keys: the variant's reward components, in critic-head order.
    """

    def __init__(self, cfg: AgentConfig, env: EnvBase) -> None:
        self.cfg = cfg
        self.obs_dim = env.observation_spec[keys.OBSERVATION].shape[-1]
        self.action_dim = env.action_spec.shape[-1]
        self.feature_shapes = env_feature_shapes(env)
        self.reward_keys = reward_keys(cfg.variant)
        #: Steps per episode (the env's ``time_limit``, else 1000): the dense heads' horizon.
        self.horizon = episode_steps(env)

    def head_supports(self) -> tuple[list[float], list[float]]:
        """Each critic head's ``(v_min, v_max)``: see :func:`gentlerl.rewards.variants.head_supports`.

        A dense head spans ``network.dense_reward_bound`` (the penalty surprise's
        ``network.penalty_surprise_bound`` where set) x the discounted horizon of
        ``time_limit`` steps (the largest return of a reward of that size at every step).
        """
        net = self.cfg.network
        horizon = discounted_horizon(self.cfg.learner.gamma, self.horizon)
        bound, rsp = net.dense_reward_bound, net.penalty_surprise_bound
        return head_supports(
            self.reward_keys,
            v_min=net.v_min,
            v_max=net.v_max,
            bounded=net.bounded_support,
            dense_span=None if bound is None else bound * horizon,
            spans=None if rsp is None else {keys.PENALTY_SURPRISE: rsp * horizon},
        )

    def make_intrinsic_rewards(self) -> IntrinsicRewards:
        return IntrinsicRewards(
            self.cfg.variant,
            self.cfg.gentleness,
            obs_dim=self.obs_dim,
            action_dim=self.action_dim,
            feature_shapes=self.feature_shapes,
            seed=self.cfg.seed,
            force_key=self.cfg.env.force,
            device=self.cfg.learner.device,  # the models learn beside the learner, launched
            compile=self.cfg.learner.compile,  # as its update is
            cudagraphs=self.cfg.learner.cudagraphs,
        )

    def make_learner(self) -> Learner:
        net, learner = self.cfg.network, self.cfg.learner
        actor = make_actor(self.obs_dim, self.action_dim, net.actor_hidden)
        v_min, v_max = self.head_supports()
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
            non_episodic_keys=[]
            if learner.episodic_intrinsic
            else intrinsic_keys(self.reward_keys),
            policy_noise=learner.policy_noise,
        )
        loss.make_value_estimator(gamma=learner.gamma)
        loss.set_keys(terminated=keys.NSTEP_TERMINATED)
        return Learner(
            loss.to(learner.device),
            lr_actor=learner.lr_actor,
            lr_critic=learner.lr_critic,
            target_update_period=learner.target_update_period,
            compile=learner.compile,
            cudagraphs=learner.cudagraphs,
        )

    def make_policy(self, learner: Learner) -> torch.nn.Module:
        """The learner's acting actor (:attr:`Learner.policy`, on the CPU) with Gaussian
        exploration noise (``collector.sigma``)."""
        return make_exploration_policy(
            learner.policy, self.cfg.collector.sigma, action_dim=self.action_dim
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
        )
        writer = NStepWriter(
            rb, replay.n_steps, self.cfg.learner.gamma, self.reward_keys, window_keys
        )
        schedule = (
            make_beta_scheduler(rb, 1.0, max(total_updates, 1)) if replay.prioritized else None
        )
        return writer, rb, schedule
