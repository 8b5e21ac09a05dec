"""Shared mechanics of the gentleness transforms: rewards of a transition (s_t, a_t, s_{t+1}).

Every transform here computes its outputs from a step's root entries (``s_t``, ``a_t``) and its
``"next"`` entries (``s_{t+1}``) and writes them under ``"next"``. The same code serves

- an env (``TransformedEnv`` / ``env.append_transform``): :meth:`_step` sees both halves;
- a collector batch, a ``Compose`` or a replay buffer sample: :meth:`forward` reads
  ``tensordict`` and ``tensordict["next"]``.

Outputs are registered in the reward spec (TorchRL's convention for intrinsic rewards, as in
``RNDTransform``), except per-site diagnostics such as ``impact`` which go in the observation spec
and are zero after a reset.
"""

from __future__ import annotations

import math
import os
from typing import Any

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torch import nn
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import Transform


class TransitionTransform(Transform):
    """Base class: subclasses implement :meth:`compute` ``(td, next_td) -> {out_key: tensor}``.

    ``scalar_out_keys`` ([1]-shaped rewards) go to the reward spec; ``observation_out_shapes``
    (key -> trailing shape) go to the observation spec and get :meth:`reset_outputs` on reset.
    """

    scalar_out_keys: tuple[str, ...] = ()

    def observation_out_shapes(self, observation_spec: Composite) -> dict[str, tuple[int, ...]]:
        return {}

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        raise NotImplementedError

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        next_tensordict.update(self.compute(tensordict, next_tensordict))
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        next_tensordict = tensordict.get("next", None)
        if next_tensordict is None:
            raise ValueError(
                f"{type(self).__name__} needs a transition: a tensordict with a 'next' entry, "
                f"got keys {sorted(map(str, tensordict.keys()))}"
            )
        next_tensordict.update(self.compute(tensordict, next_tensordict))
        return tensordict

    def read(self, tensordict: TensorDictBase | Composite, key: NestedKey) -> Any:
        """``tensordict[key]`` (or a spec's entry), else a ``ValueError`` naming the missing key
        and the ones there."""
        value = tensordict.get(key, None)
        if value is None:
            where = "env's spec" if isinstance(tensordict, Composite) else "tensordict"
            raise ValueError(
                f"{type(self).__name__} reads {key!r}, which the {where} lacks; it has "
                f"{sorted(map(str, tensordict.keys()))} (set in_keys to the env's key)"
            )
        return value

    def reset_outputs(self, tensordict_reset: TensorDictBase) -> dict[str, torch.Tensor]:
        """Values of the observation-spec outputs right after a reset (none by default)."""
        return {}

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        tensordict_reset.update(self.reset_outputs(tensordict_reset))
        return tensordict_reset

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        shapes = self.observation_out_shapes(observation_spec)
        for key, shape in shapes.items():
            observation_spec[key] = Unbounded(
                shape=(*observation_spec.shape, *shape),
                device=observation_spec.device,
                dtype=torch.float32,
            )
        return observation_spec

    def transform_reward_spec(self, reward_spec: Composite) -> Composite:
        for key in self.scalar_out_keys:
            reward_spec[key] = Unbounded(
                shape=(*reward_spec.shape, 1), device=reward_spec.device, dtype=torch.float32
            )
        return reward_spec


def check_lam(name: str, lam: Any) -> tuple[float, float]:
    r"""``lam`` as two floats :math:`[\lambda_1, \lambda_2]`, both finite and >= 0, or a
    ``ValueError`` naming ``name`` and the value."""
    try:
        values = tuple(float(v) for v in lam)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 2 or not all(math.isfinite(v) and v >= 0 for v in values):
        raise ValueError(
            f"{name} lam must be two finite numbers [lambda_1 >= 0, lambda_2 >= 0], got {lam!r}"
        )
    return values  # type: ignore[return-value]


class ModelRewardTransform(TransitionTransform):
    """A reward computed from a model that a loss trains (the RND transform / loss pair).

    Like TorchRL's ``RNDTransform``, it receives the model; it reads it with ``params`` (e.g. the
    loss's target copy, which ``HardUpdate`` refreshes in place). The reward is multiplied by
    ``scale`` and by the :attr:`active` buffer, which stays ``False`` (reward 0) until the
    training loop switches it on after the reward delay.

    It runs only in the process that built it: a copy sent to another process (a collector
    worker) reads a model that the loss's updates never reach, so :meth:`predict` raises there,
    as it does in an unpickled copy. ``copy.deepcopy`` shares the model, its parameters and the
    gate, as :meth:`clone` does (a copy with a model of its own would never learn).
    """

    def __init__(
        self,
        model: nn.Module,
        params: TensorDictBase,
        out_key: str,
        scale: float,
        in_keys: list,
    ) -> None:
        if not scale >= 0:
            raise ValueError(f"scale must be >= 0, got {scale}")
        super().__init__(in_keys=in_keys, out_keys=[out_key])
        self.scalar_out_keys = (out_key,)
        # Plain attributes, not submodules: the loss owns (and checkpoints) the model.
        self.__dict__["model"] = model
        self.__dict__["params"] = params
        self.scale = float(scale)
        self.register_buffer("active", torch.tensor(False))
        self.owner_pid = os.getpid()

    def __deepcopy__(self, memo: dict) -> ModelRewardTransform:
        return self.clone()

    def __setstate__(self, state: dict) -> None:
        super().__setstate__(state)
        self.owner_pid = None  # unpickled: its model is a copy that no update reaches

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        self.check_owner()
        return super()._step(tensordict, next_tensordict)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self.check_owner()
        return super().forward(tensordict)

    def predict(self, tensordict: TensorDictBase, params: TensorDictBase | None = None) -> Any:
        """``model.predict`` (or ``model(...)``) with :attr:`params` (or ``params``: e.g. one
        seed's row of a stack, under ``torch.vmap``), without gradient."""
        self.check_owner()
        params = self.params if params is None else params
        with torch.no_grad(), params.to_module(self.model, preserve_module_state=False):
            return self.model.predict(tensordict)

    def check_owner(self) -> None:
        """Raise unless this copy reads the model its loss trains (same process, not unpickled),
        whether or not this batch has a step the model is asked about."""
        if self.owner_pid is None:
            raise RuntimeError(
                f"{type(self).__name__} was unpickled: its model is a copy that the loss's "
                "updates never reach. Share the transform (clone() or copy.deepcopy()) instead"
            )
        if os.getpid() != self.owner_pid:
            raise RuntimeError(
                f"{type(self).__name__} runs in process {os.getpid()} but its model trains in "
                f"process {self.owner_pid}: this copy would never see an update. Apply the "
                "reward transforms in the trainer's process (to collected batches, to the "
                "batched env outside its workers, or as IntrinsicRewards.rescore_transform())"
            )

    def gate(self, dtype: torch.dtype) -> torch.Tensor:
        """What the reward is multiplied by: ``scale`` once :attr:`active`, else 0."""
        return self.scale * self.active.to(dtype)

    def _gate(self, reward: torch.Tensor) -> torch.Tensor:
        # A multiply, not a ``where``: NaN * 0 stays NaN, so a diverged model is seen (and stops
        # training) during the reward delay too, instead of surfacing when the gate opens.
        return reward * self.gate(reward.dtype)
