"""K distributional critics (one per reward component) evaluated in one batched pass.

The paper trains "a separate critic for each of the reward components" (task, penalty, penalty
surprise, dynamics surprise). Looping over K small MLPs launches K times the kernels; here every
layer holds weights shaped ``[K, in, out]`` and runs as one ``baddbmm`` over the heads, while each
head keeps parameters of its own (no sharing, no gradient leaking between heads).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from typing import Any

import torch
from tensordict.nn import TensorDictModule
from torch import nn

from gentlerl import keys
from gentlerl.functional import categorical_support
from gentlerl.models.actor import _check_sizes
from gentlerl.models.layers import HeadLayerNorm, HeadLinear


class FusedCritic(nn.Module):
    """``num_heads`` categorical critics Q_k(s, a) with the paper's architecture, fused.

    Per head: ``Linear(obs+act, h0) -> LayerNorm -> tanh -> [Linear -> ELU]* -> Linear(num_atoms)``
    (paper: 400-300 hidden units, 101 atoms on [-100, 100]).

    The critic owns its support (as Acme's D4PG networks): head k's atoms are
    ``num_atoms`` points from ``v_min[k]`` to ``v_max[k]``; ``v_min`` / ``v_max`` are a float for
    every head or one value per head, e.g. ``v_max=0`` for a reward that is never positive.

    ``forward(observation, action)`` returns ``(logits, atoms)``, both ``[..., num_heads, num_atoms]``
    (``atoms`` is an expanded view of :attr:`support`).
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        num_heads: int,
        hidden: Sequence[int] = (400, 300),
        num_atoms: int = 101,
        v_min: float | Sequence[float] = -100.0,
        v_max: float | Sequence[float] = 100.0,
    ) -> None:
        super().__init__()
        _check_sizes(obs_dim=obs_dim, action_dim=action_dim, num_heads=num_heads, hidden=hidden)
        if num_atoms < 2:
            raise ValueError(f"num_atoms must be >= 2, got {num_atoms}")
        bounds = [_per_head(v, num_heads, name) for v, name in ((v_min, "v_min"), (v_max, "v_max"))]
        if not all(lo < hi for lo, hi in zip(*bounds, strict=True)):
            raise ValueError(f"need v_min < v_max for every head, got v_min={v_min}, v_max={v_max}")
        # Plain attributes, not buffers: the support is set by the config, never learned, copied
        # to a target network or saved.
        self.v_min, self.v_max = tuple(bounds[0]), tuple(bounds[1])
        self.num_heads = num_heads
        self.num_atoms = num_atoms
        # The support on the device (and dtype) of the last forward's logits: moved once, not at
        # every call, so that a CUDA graph can capture the forward (its warm-up moves it).
        self._support = self.support
        widths = [obs_dim + action_dim, *hidden]
        self.layers = nn.ModuleList(HeadLinear(num_heads, i, o) for i, o in pairwise(widths))
        self.norm = HeadLayerNorm(num_heads, hidden[0])
        self.head = HeadLinear(num_heads, hidden[-1], num_atoms)

    @property
    def support(self) -> torch.Tensor:
        """``[num_heads, num_atoms]``: the atoms of each head."""
        v_min, v_max = torch.tensor(self.v_min), torch.tensor(self.v_max)
        return categorical_support(v_min, v_max, self.num_atoms)

    def forward(
        self, observation: torch.Tensor, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([observation, action], -1)
        batch_shape = x.shape[:-1]
        # [B, in] -> [K, B, in]: an expanded view, no copy.
        h = x.reshape(1, -1, x.shape[-1]).expand(self.num_heads, -1, -1)
        h = torch.tanh(self.norm(self.layers[0](h)))
        for layer in self.layers[1:]:
            h = nn.functional.elu(layer(h))
        logits = self.head(h)  # [K, B, atoms]
        logits = logits.transpose(0, 1).reshape(*batch_shape, self.num_heads, self.num_atoms)
        if self._support.device != logits.device or self._support.dtype != logits.dtype:
            # A loss's ``.to`` does not reach its networks' plain attributes: follow the logits.
            self._support = self.support.to(device=logits.device, dtype=logits.dtype)
        return logits, self._support.expand_as(logits)


def _per_head(value: float | Sequence[float], num_heads: int, name: str) -> list[float]:
    """``value`` for each of ``num_heads`` heads (a float is shared by all of them)."""
    if isinstance(value, int | float):
        return [float(value)] * num_heads
    values = [float(v) for v in value]
    if len(values) != num_heads:
        raise ValueError(f"{name}={list(value)} needs one value per head ({num_heads} heads)")
    return values


def make_critic(
    *args: Any,
    obs_key: str = keys.OBSERVATION,
    action_key: str = keys.ACTION,
    out_keys: Sequence[str] = (keys.STATE_ACTION_VALUE_LOGITS, keys.STATE_ACTION_VALUE_ATOMS),
    **kwargs: Any,
) -> TensorDictModule:
    """A :class:`FusedCritic` (built from ``args`` / ``kwargs``: sizes, atoms, supports) reading
    ``observation`` and ``action``, writing ``[..., K, atoms]`` logits and atoms."""
    critic = FusedCritic(*args, **kwargs)
    return TensorDictModule(critic, in_keys=[obs_key, action_key], out_keys=list(out_keys))
