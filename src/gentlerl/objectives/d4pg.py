"""Multi-head distributional DDPG (D4PG) loss: one categorical critic per reward component.

Huang et al. 2019 ("Agent architecture"): "We use a separate critic for each of the reward
components [...] The separation of the critics supports more stable learning." The actor is
trained to maximise the *sum* of the components' expected returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from tensordict.utils import NestedKey
from torchrl.objectives.common import LossModule
from torchrl.objectives.utils import _cache_values

from gentlerl import keys
from gentlerl.functional import categorical_projection, categorical_support


class MultiHeadD4PGLoss(LossModule):
    r"""D4PG loss with ``K = len(reward_keys)`` distributional critic heads.

    For each component :math:`k` with n-step return :math:`R^k` (summed by TorchRL's
    ``MultiStepTransform``) the critic target is the categorical projection (Barth-Maron et al.
    2018, eq. 7) of :math:`R^k + \gamma^n (1 - \mathrm{terminated})\, Z^k_{\bar\theta}(s', \pi_{\bar\phi}(s'))`,
    computed with the *target* actor and the *target* critic head :math:`k`:

    .. math::
        \mathcal{L}_{value} = \sum_k \mathbb{E}\left[ -\sum_j \Phi_j^k \log p_j^k(s, a) \right],
        \qquad
        \mathcal{L}_{actor} = -\mathbb{E}\left[ \sum_k \mathbb{E}[Z^k(s, \pi(s))] \right].

    Heads named in ``non_episodic_keys`` bootstrap through ``terminated`` (their discount ignores
    it), as RND treats its intrinsic return (Burda et al. 2019): ending the episode by succeeding
    then does not also end an intrinsic reward stream, so curiosity cannot outbid the task by
    keeping episodes alive. The paper does not say; by default every head is episodic.

    The critic parameters get no gradient from the actor loss. ``td_error`` (the replay priority)
    is the mean over heads of the per-sample cross-entropies, as Acme's D4PG uses the critic loss.

    Args:
        actor_network: deterministic policy, e.g. :func:`gentlerl.models.make_actor`.
        value_network: writes ``[..., K, num_atoms]`` logits, e.g. :func:`gentlerl.models.make_critic`.

    Keyword Args:
        reward_keys: the reward components, in critic-head order (read under ``"next"``).
        non_episodic_keys: components (a subset of ``reward_keys``) whose bootstrap ignores
            termination, e.g. the intrinsic ``penalty_surprise``.
        v_min, v_max: support of the categorical value distributions (paper: [-100, 100]); a float
            for every head, or one value per head (in ``reward_keys`` order), e.g. ``v_max=0`` for
            a head whose reward is never positive, such as the impact penalty: its critic then
            cannot over-estimate above the best possible value (no penalty at all).
        gamma: discount per step; the bootstrap uses ``gamma ** steps_to_next_obs``.
        policy_noise: std of the Gaussian noise added to the target actor's actions (TD3's target
            policy smoothing, Fujimoto et al. 2018; TorchRL ``TD3Loss``), clipped to
            ``[-noise_clip, noise_clip]``, the noisy action clipped to [-1, 1]. It keeps the actor
            from exploiting narrow peaks of a critic's error. 0 (default): D4PG as published.
        noise_clip: bound of that noise.
        delay_actor, delay_value: keep target copies (update them with TorchRL's
            ``HardUpdate`` / ``SoftUpdate``).
        use_prioritized_weights: weight samples by ``priority_weight`` when present ("auto").

    Examples:
        >>> from gentlerl.models import make_actor, make_critic
        >>> loss = MultiHeadD4PGLoss(make_actor(8, 2), make_critic(8, 2, num_heads=2),
        ...                          reward_keys=["reward", "penalty"])
        >>> data = TensorDict({"observation": torch.randn(4, 8), "action": torch.rand(4, 2),
        ...     "next": {"observation": torch.randn(4, 8), "reward": torch.ones(4, 1),
        ...              "penalty": -torch.ones(4, 1),
        ...              "terminated": torch.zeros(4, 1, dtype=torch.bool)}}, [4])
        >>> sorted(loss(data).keys())
        ['loss_actor', 'loss_value', 'loss_value_penalty', 'loss_value_reward', 'value_penalty', 'value_reward']
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(...)``).

        Attributes:
            value_logits: critic output, ``[..., K, num_atoms]``.
            priority: where the per-sample priority is written. Defaults to ``"td_error"``.
            terminated: read under ``"next"``; the bootstrap is cut where it is true. With
                n-step data it must be the flag of the window's *last* step (see
                :func:`gentlerl.data.make_replay_buffer`).
            steps_to_next_obs: n of each n-step transition (1 when absent).
            priority_weight: importance weights of the prioritised sampler.
        """

        value_logits: NestedKey = keys.STATE_ACTION_VALUE_LOGITS
        priority: NestedKey = keys.PRIORITY
        terminated: NestedKey = keys.TERMINATED
        steps_to_next_obs: NestedKey = "steps_to_next_obs"
        priority_weight: NestedKey = "priority_weight"

    default_keys = _AcceptedKeys
    tensor_keys: _AcceptedKeys
    actor_network: TensorDictModule
    value_network: TensorDictModule
    actor_network_params: TensorDictBase
    value_network_params: TensorDictBase
    target_actor_network_params: TensorDictBase
    target_value_network_params: TensorDictBase

    def __init__(
        self,
        actor_network: TensorDictModule,
        value_network: TensorDictModule,
        *,
        reward_keys: Sequence[NestedKey],
        non_episodic_keys: Sequence[NestedKey] = (),
        v_min: float | Sequence[float] = -100.0,
        v_max: float | Sequence[float] = 100.0,
        gamma: float = 0.99,
        policy_noise: float = 0.0,
        noise_clip: float = 0.5,
        delay_actor: bool = True,
        delay_value: bool = True,
        use_prioritized_weights: str | bool = "auto",
    ) -> None:
        super().__init__()
        if len(reward_keys) == 0:
            raise ValueError("reward_keys must name at least one reward component, got []")
        if not 0.0 <= gamma <= 1.0:
            raise ValueError(f"gamma must be in [0, 1], got {gamma}")
        if policy_noise < 0 or noise_clip < 0:
            raise ValueError(
                f"policy_noise and noise_clip must be >= 0, got {policy_noise} and {noise_clip}"
            )
        self.policy_noise, self.noise_clip = float(policy_noise), float(noise_clip)
        self.reward_keys = list(reward_keys)
        k = len(self.reward_keys)
        bounds = [_per_head(v, k, name) for v, name in ((v_min, "v_min"), (v_max, "v_max"))]
        if not all(lo < hi for lo, hi in zip(*bounds, strict=True)):
            raise ValueError(f"need v_min < v_max for every head, got v_min={v_min}, v_max={v_max}")
        self.register_buffer("v_min", torch.tensor(bounds[0]), persistent=False)
        self.register_buffer("v_max", torch.tensor(bounds[1]), persistent=False)
        unknown = [k for k in non_episodic_keys if k not in self.reward_keys]
        if unknown:
            raise ValueError(
                f"non_episodic_keys {unknown} are not reward components {self.reward_keys}"
            )
        episodic = [k not in non_episodic_keys for k in self.reward_keys]
        self.register_buffer("episodic", torch.tensor(episodic), persistent=False)
        self.gamma = float(gamma)
        self.use_prioritized_weights = use_prioritized_weights
        self.reduction = "mean"
        self.convert_to_functional(actor_network, "actor_network", create_target_params=delay_actor)
        self.convert_to_functional(value_network, "value_network", create_target_params=delay_value)
        self.actor_in_keys = list(actor_network.in_keys)
        self.action_key = actor_network.out_keys[0]
        self.value_in_keys = list(value_network.in_keys)

    def _value_logits(self, td: TensorDictBase, params: TensorDictBase) -> torch.Tensor:
        with params.to_module(self.value_network, preserve_module_state=False):
            return self.value_network(td)[self.tensor_keys.value_logits]

    def _act(self, td: TensorDictBase, params: TensorDictBase) -> TensorDictBase:
        with params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network(td)

    def _support(self, logits: torch.Tensor) -> torch.Tensor:
        """``[K, num_atoms]``: the atoms of each head."""
        return categorical_support(self.v_min, self.v_max, logits.shape[-1]).to(logits.dtype)

    def _check_heads(self, logits: torch.Tensor) -> None:
        if logits.shape[-2] != len(self.reward_keys):
            raise ValueError(
                f"value network has {logits.shape[-2]} heads but reward_keys has "
                f"{len(self.reward_keys)}: {self.reward_keys}"
            )

    @torch.no_grad()
    def target_distribution(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Projected targets ``[B, K, num_atoms]`` from the target actor and target critics."""
        next_td = tensordict.get("next").select(
            *self.actor_in_keys, *self.value_in_keys, strict=False
        )
        next_td = self._act(next_td, self.target_actor_network_params)
        if self.policy_noise > 0:
            action = next_td.get(self.action_key)
            noise = torch.randn_like(action) * self.policy_noise
            noise = noise.clamp(-self.noise_clip, self.noise_clip)
            next_td.set(self.action_key, (action + noise).clamp(-1.0, 1.0))
        next_logits = self._value_logits(next_td, self.target_value_network_params)
        self._check_heads(next_logits)
        batch = tensordict.batch_size
        reward = torch.cat(
            [tensordict.get(("next", k)).reshape(*batch, 1) for k in self.reward_keys], -1
        )
        steps = tensordict.get(self.tensor_keys.steps_to_next_obs, None)
        steps = reward.new_ones(*batch, 1) if steps is None else steps.reshape(*batch, 1)
        terminated = tensordict.get(("next", self.tensor_keys.terminated)).reshape(*batch, 1)
        cut = terminated.bool() & self.episodic  # [B, K]: non-episodic heads bootstrap anyway
        discount = self.gamma ** steps.to(reward.dtype) * (~cut).to(reward.dtype)
        return categorical_projection(
            next_logits.softmax(-1), reward, discount, self.v_min, self.v_max
        )

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        """Critic and actor losses on a (n-step) batch; writes ``td_error`` into ``tensordict``."""
        weights = self._maybe_get_priority_weight(tensordict)
        target = self.target_distribution(tensordict)

        td = tensordict.select(*self.value_in_keys, strict=False).detach()
        logits = self._value_logits(td, self.value_network_params)
        self._check_heads(logits)
        cross_entropy = -(target * logits.log_softmax(-1)).sum(-1)  # [B, K]
        per_head = [
            self._reduce_loss(cross_entropy[..., k], tensordict=tensordict, weights=weights)
            for k in range(len(self.reward_keys))
        ]
        priority = cross_entropy.detach().mean(-1)
        tensordict.set(self.tensor_keys.priority, priority, inplace=True)

        actor_td = self._act(
            tensordict.select(*self.actor_in_keys, strict=False).detach(), self.actor_network_params
        )
        actor_logits = self._value_logits(actor_td, self._cached_detached_value_params)
        q_per_head = (actor_logits.softmax(-1) * self._support(actor_logits)).sum(-1)  # [B, K]
        loss_actor = self._reduce_loss(-q_per_head.sum(-1), tensordict=tensordict, weights=weights)

        out = {"loss_actor": loss_actor, "loss_value": torch.stack(per_head).sum()}
        for k, key in enumerate(self.reward_keys):
            name = key if isinstance(key, str) else "_".join(key)
            out[f"loss_value_{name}"] = per_head[k]
            out[f"value_{name}"] = q_per_head[..., k].detach().mean()
        return TensorDict(out, batch_size=[])

    @property
    @_cache_values
    def _cached_detached_value_params(self) -> TensorDictBase:
        return self.value_network_params.detach()


def _per_head(value: float | Sequence[float], num_heads: int, name: str) -> list[float]:
    """``value`` for each of ``num_heads`` heads (a float is shared by all of them)."""
    if isinstance(value, int | float):
        return [float(value)] * num_heads
    values = [float(v) for v in value]
    if len(values) != num_heads:
        raise ValueError(f"{name}={list(value)} needs one value per head ({num_heads} heads)")
    return values
