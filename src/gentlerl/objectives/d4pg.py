"""Multi-head distributional DDPG (D4PG) loss: one categorical critic per reward component.

Huang et al. 2019 ("Agent architecture"): "We use a separate critic for each of the reward
components [...] The separation of the critics supports more stable learning." The actor
maximises the (weighted) *sum* of the components' expected returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from tensordict.utils import NestedKey, unravel_key
from torchrl.objectives.common import LossModule
from torchrl.objectives.utils import ValueEstimators

from gentlerl import keys
from gentlerl.functional import normalized_values
from gentlerl.objectives.value import CategoricalTD0


class MultiHeadD4PGLoss(LossModule):
    r"""D4PG loss with ``K = len(reward_keys)`` distributional critic heads.

    For each component :math:`k` with n-step return :math:`R^k` (summed by TorchRL's
    ``MultiStepTransform``) the critic target is the categorical projection (Barth-Maron et al.
    2018, eq. 7) of :math:`R^k + \gamma^n (1 - \mathrm{terminated})\, Z^k_{\bar\theta}(s', \pi_{\bar\phi}(s'))`,
    computed with the *target* actor and the *target* critic head :math:`k`:

    .. math::
        \mathcal{L}_{value} = \sum_k \mathbb{E}\left[ -\sum_j \Phi_j^k \log p_j^k(s, a) \right],
        \qquad
        \mathcal{L}_{actor} = -\mathbb{E}\left[ \sum_k w_k\, \mathbb{E}[Z^k(s, \pi(s))] \right],

    :math:`w_k` = :attr:`head_weights` (1: the paper; :meth:`set_head_weight`); with
    ``normalize_values`` each head's :math:`\mathbb{E}[Z^k]` is divided by its batch mean
    magnitude. The critic owns the supports: it writes each head's ``atoms`` next to its logits
    (:func:`~gentlerl.models.make_critic`).
    Discounting is the value estimator's (:meth:`make_value_estimator`, TD(0) on n-step data), as
    in TorchRL. Heads in ``non_episodic_keys`` bootstrap through ``terminated``, as RND treats its
    intrinsic return (Burda et al. 2019); the paper does not say, and by default all are episodic.

    :meth:`loss_value` and :meth:`loss_actor` can be called alone; the critic parameters get no
    gradient from the actor loss. ``td_error`` (the replay priority) is the mean over heads of the
    per-sample cross-entropies, as Acme's D4PG uses the critic loss.

    Args:
        actor_network: deterministic policy, e.g. :func:`gentlerl.models.make_actor`.
        value_network: writes ``[..., K, num_atoms]`` logits and atoms, e.g.
            :func:`gentlerl.models.make_critic`.

    Keyword Args:
        reward_keys: the reward components, in critic-head order (read under ``"next"``); rename
            them later with ``set_keys(rewards=[...])``.
        non_episodic_keys: components (a subset of ``reward_keys``) whose bootstrap ignores
            termination, e.g. the intrinsic ``penalty_surprise``.
        policy_noise: std of the Gaussian noise on the target actor's actions (TD3's target policy
            smoothing), clipped to ``[-noise_clip, noise_clip]``; 0 (default): D4PG as published.
        noise_clip: bound of that noise (the noisy action is clipped to [-1, 1]).
        delay_actor, delay_value: keep target copies (TorchRL's ``HardUpdate`` / ``SoftUpdate``).
        use_prioritized_weights: weight samples by ``priority_weight`` when present ("auto").
        normalize_values: the actor sums :math:`w_k \hat Q_k`, each head divided by its batch's
            mean magnitude (:func:`~gentlerl.functional.normalized_values`), so that rescaling
            one component's rewards (and its support) leaves the trade-off unchanged (Method IV);
            False (default): the paper's sum of the heads' returns.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from gentlerl.models import make_actor, make_critic
        >>> critic = make_critic(8, 2, num_heads=2, v_min=-10.0, v_max=[10.0, 0.0])
        >>> loss = MultiHeadD4PGLoss(make_actor(8, 2), critic, reward_keys=["reward", "penalty"])
        >>> loss.make_value_estimator(gamma=0.9)
        >>> data = TensorDict({"observation": torch.randn(4, 8), "action": torch.rand(4, 2),
        ...     "next": {"observation": torch.randn(4, 8), "reward": torch.ones(4, 1),
        ...              "penalty": -torch.ones(4, 1),
        ...              "terminated": torch.zeros(4, 1, dtype=torch.bool)}}, [4])
        >>> sorted(loss(data).keys())
        ['loss_actor', 'loss_value', 'loss_value_penalty', 'loss_value_reward', 'value_penalty', 'value_reward']
        >>> loss.loss_actor(data)[1]["value"].shape
        torch.Size([2])
    """

    @dataclass
    class _AcceptedKeys:
        """Configurable tensordict keys (``loss.set_keys(...)``).

        Attributes:
            rewards: the reward components, one per critic head (read under ``"next"``).
            value_logits: critic logits, ``[..., K, num_atoms]``.
            value_atoms: the critic's atoms, ``[..., K, num_atoms]``.
            priority: where the per-sample priority is written. Defaults to ``"td_error"``.
            terminated: read under ``"next"``; the bootstrap is cut where it is true. With
                n-step data it must be the flag of the window's *last* step (see
                :func:`gentlerl.data.make_replay_buffer`).
            steps_to_next_obs: n of each n-step transition (1 when absent).
            priority_weight: importance weights of the prioritised sampler.
        """

        rewards: tuple[NestedKey, ...] = field(default=(keys.REWARD,))
        value_logits: NestedKey = keys.STATE_ACTION_VALUE_LOGITS
        value_atoms: NestedKey = keys.STATE_ACTION_VALUE_ATOMS
        priority: NestedKey = keys.PRIORITY
        terminated: NestedKey = keys.TERMINATED
        steps_to_next_obs: NestedKey = "steps_to_next_obs"
        priority_weight: NestedKey = "priority_weight"

    default_keys = _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0
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
        policy_noise: float = 0.0,
        noise_clip: float = 0.5,
        delay_actor: bool = True,
        delay_value: bool = True,
        use_prioritized_weights: str | bool = "auto",
        normalize_values: bool = False,
    ) -> None:
        super().__init__()
        if len(reward_keys) == 0:
            raise ValueError("reward_keys must name at least one reward component, got []")
        if policy_noise < 0 or noise_clip < 0:
            raise ValueError(
                f"policy_noise and noise_clip must be >= 0, got {policy_noise} and {noise_clip}"
            )
        unknown = [k for k in non_episodic_keys if k not in reward_keys]
        if unknown:
            raise ValueError(f"non_episodic_keys {unknown} are not reward components {reward_keys}")
        self.policy_noise, self.noise_clip = float(policy_noise), float(noise_clip)
        self.num_heads = len(reward_keys)
        self.set_keys(rewards=tuple(reward_keys))
        episodic = [k not in non_episodic_keys for k in reward_keys]
        self.register_buffer("episodic", torch.tensor(episodic), persistent=False)
        self.register_buffer("head_weights", torch.ones(self.num_heads), persistent=False)
        self.use_prioritized_weights = use_prioritized_weights
        self.normalize_values = bool(normalize_values)
        self.reduction = "mean"
        self.convert_to_functional(actor_network, "actor_network", create_target_params=delay_actor)
        self.convert_to_functional(value_network, "value_network", create_target_params=delay_value)
        self.actor_in_keys = list(actor_network.in_keys)
        self.action_key = actor_network.out_keys[0]
        self.value_in_keys = list(value_network.in_keys)

    @property
    def in_keys(self) -> list[NestedKey]:
        """Every entry the losses read (the priority weights whether or not they are used)."""
        t = self.tensor_keys
        states = [k for k in (*self.actor_in_keys, *self.value_in_keys) if k != self.action_key]
        nxt = [("next", k) for k in (*states, *t.rewards)]
        keys_ = {*self.actor_in_keys, *self.value_in_keys, *nxt, ("next", t.terminated)}
        keys_ |= {t.steps_to_next_obs, t.priority_weight}
        return sorted((unravel_key(k) for k in keys_), key=str)

    @property
    def reward_keys(self) -> list[NestedKey]:
        return list(self.tensor_keys.rewards)

    def _forward_value_estimator_keys(self, **kwargs: object) -> None:
        rewards = kwargs.get("rewards")
        if rewards is not None and len(rewards) != self.num_heads:
            raise ValueError(
                f"rewards={list(rewards)} must name one reward per critic head ({self.num_heads})"
            )

    def make_value_estimator(
        self, value_type: ValueEstimators | None = None, *, gamma: float = 0.99
    ) -> None:
        """Set the discounting of the critic targets: only TD(0) on (n-step) data is supported."""
        if value_type not in (None, ValueEstimators.TD0):
            raise NotImplementedError(f"{type(self).__name__} supports TD0 only, got {value_type}")
        self._value_estimator = CategoricalTD0(gamma)

    def _default_value_estimator(self) -> None:
        self.make_value_estimator()

    def _critic(self, td: TensorDictBase, params: TensorDictBase) -> tuple[torch.Tensor, ...]:
        """``(logits, atoms)`` of the critic with ``params``."""
        with params.to_module(self.value_network, preserve_module_state=False):
            out = self.value_network(td)
        logits = out.get(self.tensor_keys.value_logits)
        if logits.shape[-2] != self.num_heads:
            raise ValueError(
                f"value network has {logits.shape[-2]} heads but there are {self.num_heads} "
                f"reward keys: {self.reward_keys}"
            )
        return logits, out.get(self.tensor_keys.value_atoms)

    def _act(self, td: TensorDictBase, params: TensorDictBase) -> TensorDictBase:
        with params.to_module(self.actor_network, preserve_module_state=False):
            return self.actor_network(td)

    def network_params(self) -> TensorDict:
        """The four parameter sets the losses read (online and target actor and critic), as one
        tensordict: :meth:`losses` with a stack of them runs several agents at once (``vmap``)."""
        names = ("actor", "value", "target_actor", "target_value")
        return TensorDict({n: getattr(self, f"{n}_network_params") for n in names}, [])

    @torch.no_grad()
    def target_distribution(
        self, tensordict: TensorDictBase, params: TensorDictBase | None = None
    ) -> torch.Tensor:
        """Projected targets ``[B, K, num_atoms]`` from the target actor and target critics
        (``params``: :meth:`network_params`, the loss's own by default)."""
        params = self.network_params() if params is None else params
        next_td = tensordict.get("next").select(
            *self.actor_in_keys, *self.value_in_keys, strict=False
        )
        next_td = self._act(next_td, params["target_actor"])
        if self.policy_noise > 0:
            action = next_td.get(self.action_key)
            noise = torch.randn_like(action) * self.policy_noise
            noise = noise.clamp(-self.noise_clip, self.noise_clip)
            next_td.set(self.action_key, (action + noise).clamp(-1.0, 1.0))
        next_logits, next_atoms = self._critic(next_td, params["target_value"])
        batch = tensordict.batch_size
        reward = torch.cat(
            [tensordict.get(("next", k)).reshape(*batch, 1) for k in self.reward_keys], -1
        )
        steps = tensordict.get(self.tensor_keys.steps_to_next_obs, None)
        steps = reward.new_ones(*batch, 1) if steps is None else steps.reshape(*batch, 1)
        terminated = tensordict.get(("next", self.tensor_keys.terminated)).reshape(*batch, 1)
        cut = terminated.bool() & self.episodic  # [B, K]: non-episodic heads bootstrap anyway
        return self.value_estimator.target(next_logits, next_atoms, reward, steps, cut)

    def _value_terms(
        self, tensordict: TensorDictBase, params: TensorDictBase
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``([K] per-head critic losses, [B] priorities)``; the batch is left alone."""
        weights = self._maybe_get_priority_weight(tensordict)
        target = self.target_distribution(tensordict, params)
        td = tensordict.select(*self.value_in_keys, strict=False).detach()
        logits, _ = self._critic(td, params["value"])
        cross_entropy = -(target * logits.log_softmax(-1)).sum(-1)  # [B, K]
        per_head = [
            self._reduce_loss(cross_entropy[..., k], tensordict=tensordict, weights=weights)
            for k in range(self.num_heads)
        ]
        return torch.stack(per_head), cross_entropy.detach().mean(-1)

    def loss_value(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, dict]:
        """Summed cross-entropy of the K critics, ``{"per_head": [K] losses}``; writes
        ``td_error`` into ``tensordict``."""
        per_head, priority = self._value_terms(tensordict, self.network_params())
        tensordict.set(self.tensor_keys.priority, priority, inplace=True)
        return per_head.sum(), {"per_head": per_head}

    def _actor_terms(
        self, tensordict: TensorDictBase, params: TensorDictBase
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(actor loss, [K] mean expected returns)``; the critics get no gradient from it."""
        weights = self._maybe_get_priority_weight(tensordict)
        actor_td = self._act(
            tensordict.select(*self.actor_in_keys, strict=False).detach(), params["actor"]
        )
        logits, atoms = self._critic(actor_td, params["value"].detach())
        q_per_head = (logits.softmax(-1) * atoms).sum(-1)  # [B, K]
        heads = q_per_head
        if self.normalize_values:  # units cannot tip the sum of the heads
            heads = normalized_values(q_per_head, atoms[..., -1] - atoms[..., 0])
        objective = (heads * self.head_weights).sum(-1)
        loss = self._reduce_loss(-objective, tensordict=tensordict, weights=weights)
        return loss, q_per_head.detach().reshape(-1, self.num_heads).mean(0)

    def loss_actor(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, dict]:
        """Minus the weighted sum of the K heads' expected returns at ``(s, pi(s))``,
        ``{"value": [K] mean expected returns}``."""
        loss, value = self._actor_terms(tensordict, self.network_params())
        return loss, {"value": value}

    def set_head_weight(self, key: NestedKey, weight: float) -> None:
        """``key``'s :math:`w_k`, in place (a captured graph reads it): e.g. 1 + a multiplier."""
        if key not in self.reward_keys:
            raise KeyError(f"set_head_weight: {key!r} is not one of the heads {self.reward_keys}")
        self.head_weights[self.reward_keys.index(key)] = float(weight)

    def losses(
        self, tensordict: TensorDictBase, params: TensorDictBase
    ) -> tuple[TensorDict, torch.Tensor]:
        """Critic and actor losses of the agent whose parameters are ``params``
        (:meth:`network_params`) and the per-sample priorities; a pure function of its inputs
        (the batch is not written), so ``torch.vmap`` can run a stack of agents at once."""
        per_head, priority = self._value_terms(tensordict, params)
        loss_actor, value = self._actor_terms(tensordict, params)
        out = {"loss_actor": loss_actor, "loss_value": per_head.sum()}
        for k, key in enumerate(self.reward_keys):
            name = key if isinstance(key, str) else "_".join(key)
            out[f"loss_value_{name}"] = per_head[k]
            out[f"value_{name}"] = value[k]
        return TensorDict(out, batch_size=[]), priority

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        """Critic and actor losses on a (n-step) batch; writes ``td_error`` into ``tensordict``."""
        out, priority = self.losses(tensordict, self.network_params())
        tensordict.set(self.tensor_keys.priority, priority, inplace=True)
        return out
