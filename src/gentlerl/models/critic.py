"""K distributional critics (one per reward component) evaluated in one batched pass.

The paper trains "a separate critic for each of the reward components" (task, penalty, penalty
surprise, dynamics surprise). Looping over K small MLPs launches K times the kernels; here every
layer holds weights shaped ``[K, in, out]`` and runs as one ``baddbmm`` over the heads, while each
head keeps parameters of its own (no sharing, no gradient leaking between heads).
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import torch
from tensordict.nn import TensorDictModule
from torch import nn

from gentlerl import keys
from gentlerl.models.actor import _check_sizes
from gentlerl.models.layers import HeadLayerNorm, HeadLinear


class FusedCritic(nn.Module):
    """``num_heads`` categorical critics Q_k(s, a) with the paper's architecture, fused.

    Per head: ``Linear(obs+act, h0) -> LayerNorm -> tanh -> [Linear -> ELU]* -> Linear(num_atoms)``
    (paper: 400-300 hidden units, 101 atoms on [-100, 100]).

    ``forward(observation, action)`` returns logits ``[..., num_heads, num_atoms]``.
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        num_heads: int,
        hidden: Sequence[int] = (400, 300),
        num_atoms: int = 101,
    ) -> None:
        super().__init__()
        _check_sizes(obs_dim=obs_dim, action_dim=action_dim, num_heads=num_heads, hidden=hidden)
        if num_atoms < 2:
            raise ValueError(f"num_atoms must be >= 2, got {num_atoms}")
        self.num_heads = num_heads
        self.num_atoms = num_atoms
        widths = [obs_dim + action_dim, *hidden]
        self.layers = nn.ModuleList(HeadLinear(num_heads, i, o) for i, o in pairwise(widths))
        self.norm = HeadLayerNorm(num_heads, hidden[0])
        self.head = HeadLinear(num_heads, hidden[-1], num_atoms)

    def forward(self, observation: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        x = torch.cat([observation, action], -1)
        batch_shape = x.shape[:-1]
        # [B, in] -> [K, B, in]: an expanded view, no copy.
        h = x.reshape(1, -1, x.shape[-1]).expand(self.num_heads, -1, -1)
        h = torch.tanh(self.norm(self.layers[0](h)))
        for layer in self.layers[1:]:
            h = nn.functional.elu(layer(h))
        logits = self.head(h)  # [K, B, atoms]
        return logits.transpose(0, 1).reshape(*batch_shape, self.num_heads, self.num_atoms)


def make_critic(
    obs_dim: int,
    action_dim: int,
    num_heads: int,
    hidden: Sequence[int] = (400, 300),
    num_atoms: int = 101,
    *,
    obs_key: str = keys.OBSERVATION,
    action_key: str = keys.ACTION,
    out_key: str = keys.STATE_ACTION_VALUE_LOGITS,
) -> TensorDictModule:
    """A :class:`FusedCritic` reading ``observation`` and ``action``, writing ``[..., K, atoms]`` logits."""
    critic = FusedCritic(obs_dim, action_dim, num_heads, hidden, num_atoms)
    return TensorDictModule(critic, in_keys=[obs_key, action_key], out_keys=[out_key])
