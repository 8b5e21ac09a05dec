"""The D4PG actor of the paper ("Agent architecture and implementation details")."""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import AdditiveGaussianModule

from gentlerl import keys


def _check_sizes(**sizes: int | Sequence[int]) -> None:
    for name, value in sizes.items():
        values = value if isinstance(value, Sequence) else [value]
        if len(values) == 0 or any(int(v) <= 0 for v in values):
            raise ValueError(f"{name} must be positive (and non-empty), got {value!r}")


def paper_trunk(in_dim: int, hidden: Sequence[int]) -> list[nn.Module]:
    """Hidden layers of the paper's actor and critics.

    "The first hidden layer is followed by layer normalization and a tanh, and all other hidden
    layers are followed by exponential linear unit (ELU) activations."
    """
    layers: list[nn.Module] = [nn.Linear(in_dim, hidden[0]), nn.LayerNorm(hidden[0]), nn.Tanh()]
    for prev, width in pairwise(hidden):
        layers += [nn.Linear(prev, width), nn.ELU()]
    return layers


def make_actor(
    obs_dim: int,
    action_dim: int,
    hidden: Sequence[int] = (300, 200),
    *,
    obs_key: str = keys.OBSERVATION,
    action_key: str = keys.ACTION,
) -> TensorDictModule:
    """Deterministic policy ``a = tanh(MLP(s))`` in [-1, 1] (paper: 300-200 hidden units).

    The output is the hand env's *delta position* action; the env scales and clips it.
    Reads ``observation`` and writes ``action``.
    """
    _check_sizes(obs_dim=obs_dim, action_dim=action_dim, hidden=hidden)
    net = nn.Sequential(*paper_trunk(obs_dim, hidden), nn.Linear(hidden[-1], action_dim), nn.Tanh())
    return TensorDictModule(net, in_keys=[obs_key], out_keys=[action_key])


def make_exploration_policy(
    actor: TensorDictModule,
    sigma: float = 0.3,
    *,
    action_dim: int | None = None,
    action_key: str = keys.ACTION,
) -> TensorDictSequential:
    """The actor followed by TorchRL's additive Gaussian noise (paper/Acme D4PG: sigma = 0.3).

    The noise is constant (no annealing) and the noisy action is clipped to [-1, 1].
    """
    if not sigma >= 0:
        raise ValueError(f"sigma must be >= 0, got {sigma}")
    if action_dim is None:
        action_dim = actor.module[-2].out_features
    spec = Bounded(-torch.ones(action_dim), torch.ones(action_dim), (action_dim,))
    noise = AdditiveGaussianModule(
        spec=spec,
        sigma_init=float(sigma),
        sigma_end=float(sigma),
        annealing_num_steps=1,
        action_key=action_key,
    )
    return TensorDictSequential(actor, noise)
