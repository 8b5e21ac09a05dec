r"""``SumRewards``: the reward components summed into the one reward a single-critic agent reads.

gentlerl's D4PG gives each component its own critic head and the actor maximises their sum; SAC,
TD3 or PPO read one ``("next", "reward")``. :class:`SumRewards` writes it,

.. math::
    r^{\mathrm{sum}}_t = \sum_k w_k\, r^k_t \qquad \text{(e.g. } r + r^f + r^{s_p}\text{)},

which is the quantity gentlerl's actor maximises (the sum of its heads' values is the value of
the summed reward, by linearity of the expected return).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import Compose, RewardSum, Transform

from gentlerl import keys


class SumRewards(Transform):
    r"""Writes ``("next", out_key)`` :math:`= \sum_k w_k\,` ``("next", in_keys[k])``.

    After it, the env has one reward (``env.reward_key`` is ``out_key``): the components move
    from the reward spec to the observation spec, where they stay readable per step (zero after
    a reset), as ``impact`` is. When ``out_key`` is one of ``in_keys`` (the env's ``reward``),
    the env's own value is kept as ``task_key`` and summed from there, so applying the
    transform again to a stored batch (after a component was recomputed at sampling) gives the
    new sum, not the sum of a sum.

    Put TorchRL's ``RewardSum`` *before* it if ``episode_reward`` should be the task's return:
    a ``RewardSum`` after it that reads ``out_key`` would sum the combined reward, and is refused
    at the first step.

    Args:
        in_keys: the reward components under ``"next"``, e.g.
            ``["reward", "penalty", "penalty_surprise"]``.
        out_key: where the sum goes (default ``"reward"``).
        weights: one factor per component (default: 1 each).
        task_key: where the env's ``out_key`` is kept when it is a component.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> td = TensorDict({"next": {"reward": torch.ones(1), "penalty": -0.25 * torch.ones(1)}})
        >>> td = SumRewards(["reward", "penalty"])(td)
        >>> td["next", "reward"].item(), td["next", "task_reward"].item()
        (0.75, 1.0)
    """

    def __init__(
        self,
        in_keys: Sequence[str],
        out_key: str = keys.REWARD,
        *,
        weights: Sequence[float] | None = None,
        task_key: str = keys.TASK_REWARD,
    ) -> None:
        in_keys = list(in_keys)
        if not in_keys or len(set(in_keys)) != len(in_keys):
            raise ValueError(f"SumRewards needs distinct reward keys to sum, got {in_keys}")
        if weights is None:
            weights = [1.0] * len(in_keys)
        if len(weights) != len(in_keys):
            raise ValueError(
                f"SumRewards: {len(weights)} weights for {len(in_keys)} keys {in_keys}"
            )
        if task_key in in_keys:
            raise ValueError(f"SumRewards: task_key {task_key!r} is also one of {in_keys}")
        super().__init__(in_keys=in_keys, out_keys=[out_key])
        self.weights = [float(w) for w in weights]
        if not all(math.isfinite(w) for w in self.weights):
            raise ValueError(f"SumRewards: weights must be finite numbers, got {list(weights)}")
        self.task_key = task_key
        self._order_checked = False

    def set_weight(self, key: str, weight: float) -> None:
        """The factor of component ``key`` from now on (a sampled batch is summed again by
        :class:`~gentlerl.rewards.RescoreRewards`), e.g. ``ImpactMultiplier.weight`` on
        ``"penalty"``: a single-critic agent's Lagrange-weighted impact penalty. The weights are
        in no state dict: a resumed agent sets them again (from ``ImpactMultiplier.weight``)."""
        if key not in self.in_keys:
            raise KeyError(f"SumRewards: {key!r} is not one of the summed keys {self.in_keys}")
        if not math.isfinite(weight):
            raise ValueError(f"SumRewards: a weight must be a finite number, got {weight}")
        self.weights[self.in_keys.index(key)] = float(weight)

    @property
    def sources(self) -> list[str]:
        """The keys summed: ``in_keys`` with ``out_key`` read from ``task_key``."""
        out = self.out_keys[0]
        return [self.task_key if k == out else k for k in self.in_keys]

    @property
    def moved(self) -> list[str]:
        """The reward-spec entries that become observations: the components and ``task_key``."""
        return [k for k in self.sources if k != self.out_keys[0]]

    def _sum(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        out = self.out_keys[0]
        if out in self.in_keys and self.task_key not in next_tensordict.keys():
            next_tensordict.set(self.task_key, next_tensordict.get(out))
        total = None
        for key, weight in zip(self.sources, self.weights, strict=True):
            value = next_tensordict.get(key, None)
            if value is None:
                raise KeyError(
                    f"SumRewards sums {key!r}, which the tensordict's 'next' lacks; it has "
                    f"{sorted(map(str, next_tensordict.keys()))}"
                )
            if total is not None and value.shape != total.shape:
                raise ValueError(
                    f"SumRewards: {key!r} is shaped {tuple(value.shape)}, the others "
                    f"{tuple(total.shape)}"
                )
            total = weight * value if total is None else total + weight * value
        next_tensordict.set(out, total)
        return next_tensordict

    def _check_order(self) -> None:
        """Refuse a ``RewardSum`` placed after this transform that reads the summed key."""
        self._order_checked = True
        ref = self.__dict__.get("_container")  # the Compose holding it (``container`` is the env)
        container = ref() if ref is not None else None
        if not isinstance(container, Compose):
            return
        transforms = list(container.transforms)
        for later in transforms[transforms.index(self) + 1 :]:
            if isinstance(later, RewardSum) and self.out_keys[0] in later.in_keys:
                raise ValueError(
                    f"RewardSum after SumRewards sums the combined {self.out_keys[0]!r} into "
                    f"{later.out_keys}: put RewardSum before SumRewards for the task's return"
                )

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        if not self._order_checked:
            self._check_order()
        return self._sum(next_tensordict)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        next_tensordict = tensordict.get("next", None)
        if next_tensordict is None:
            raise ValueError(
                "SumRewards needs a transition: a tensordict with a 'next' entry, got keys "
                f"{sorted(map(str, tensordict.keys()))}"
            )
        self._sum(next_tensordict)
        return tensordict

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        # the moved components' observation specs (transform_output_spec): their zero at reset
        observations = self.container.full_observation_spec
        for key in self.moved:
            tensordict_reset.set(key, observations[key].zero())
        return tensordict_reset

    def transform_output_spec(self, output_spec: Composite) -> Composite:
        rewards = output_spec["full_reward_spec"]
        observations = output_spec["full_observation_spec"]
        out = self.out_keys[0]
        missing = [k for k in self.in_keys if k not in rewards.keys()]
        if missing:
            raise KeyError(
                f"SumRewards sums {missing}, which the env's reward spec lacks; it has "
                f"{sorted(map(str, rewards.keys()))} (append the reward transforms first)"
            )
        template = rewards[self.in_keys[0]]
        for key in self.moved:
            source = out if key == self.task_key else key
            observations[key] = rewards[source].clone()
        for key in self.in_keys:
            if key != out:
                del rewards[key]
        rewards[out] = Unbounded(shape=template.shape, device=template.device, dtype=template.dtype)
        return output_spec
