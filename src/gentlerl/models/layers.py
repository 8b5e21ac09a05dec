"""Batched building blocks: K independent layers in one op, and running input normalisation."""

from __future__ import annotations

import math

import torch
from torch import nn
from torchrl.envs.transforms.rnd import RunningMeanStd


class HeadLinear(nn.Module):
    """``K`` independent linear layers, weights ``[K, in, out]``, on inputs ``[K, B, in]``.

    One ``baddbmm`` evaluates every head (critic head or ensemble member). Each head is
    initialised like a separate ``nn.Linear(in, out)``: U(-1/sqrt(in), 1/sqrt(in)); with
    ``generators`` (one per head) each head draws from its own seeded stream.
    """

    def __init__(
        self,
        num_heads: int,
        in_features: int,
        out_features: int,
        generators: list[torch.Generator] | None = None,
    ) -> None:
        super().__init__()
        bound = 1.0 / math.sqrt(in_features)
        weight = torch.empty(num_heads, in_features, out_features)
        bias = torch.empty(num_heads, 1, out_features)
        if generators is None:
            weight.uniform_(-bound, bound)
            bias.uniform_(-bound, bound)
        else:
            for k, gen in enumerate(generators):  # init only, not a hot path
                weight[k].uniform_(-bound, bound, generator=gen)
                bias[k].uniform_(-bound, bound, generator=gen)
        self.weight = nn.Parameter(weight)
        self.bias = nn.Parameter(bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.bias, x, self.weight)


class HeadLayerNorm(nn.Module):
    """LayerNorm over the features of each head with per-head affine parameters ``[K, 1, F]``."""

    def __init__(self, num_heads: int, features: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.ones(num_heads, 1, features))
        self.bias = nn.Parameter(torch.zeros(num_heads, 1, features))
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = nn.functional.layer_norm(x, x.shape[-1:], eps=self.eps)
        return torch.addcmul(self.bias, x, self.weight)


class RunningNorm(RunningMeanStd):
    """TorchRL's ``RunningMeanStd`` (Welford/Chan running moments as buffers) with a std floor.

    The std is floored at ``min_std`` so that near-constant features (a fingertip that never
    touched anything) do not blow up; ``denormalize`` inverts ``normalize``.
    """

    def __init__(self, dim: int, min_std: float = 1e-3) -> None:
        if min_std <= 0:
            raise ValueError(f"min_std must be > 0, got {min_std}")
        super().__init__(shape=(dim,))
        self.min_std = min_std

    @property
    def std(self) -> torch.Tensor:
        return self.var.sqrt().clamp_min(self.min_std)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.std + self.mean
