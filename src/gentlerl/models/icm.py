"""Intrinsic Curiosity Module (Pathak et al. 2017), for continuous actions — the paper's baseline."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from torch import nn

from gentlerl import keys
from gentlerl.models.actor import _check_sizes


def _mlp(sizes: Sequence[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ICMModel(nn.Module):
    r"""Feature encoder :math:`\phi`, inverse model :math:`g` and forward model :math:`f`.

    - inverse: :math:`\hat a_t = g(\phi(s_t), \phi(s_{t+1}))`, trained with MSE (continuous actions);
    - forward: :math:`\hat\phi(s_{t+1}) = f(\phi(s_t), a_t)`;
    - reward: :math:`r^i_t = \frac{\eta}{2} \lVert \hat\phi(s_{t+1}) - \phi(s_{t+1}) \rVert^2`.
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        feature_dim: int = 64,
        hidden: int = 128,
        *,
        obs_key: str = keys.OBSERVATION,
        action_key: str = keys.ACTION,
    ) -> None:
        super().__init__()
        self.obs_key, self.action_key = obs_key, action_key
        _check_sizes(obs_dim=obs_dim, action_dim=action_dim, feature_dim=feature_dim, hidden=hidden)
        self.encoder = _mlp([obs_dim, hidden, feature_dim])
        self.inverse = _mlp([2 * feature_dim, hidden, action_dim])
        self.forward_model = _mlp([feature_dim + action_dim, hidden, feature_dim])

    def forward(
        self, obs: torch.Tensor, action: torch.Tensor, next_obs: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Returns ``(predicted_action, predicted_next_features, next_features)``."""
        phi, next_phi = self.encoder(obs), self.encoder(next_obs)
        predicted_action = torch.tanh(self.inverse(torch.cat([phi, next_phi], -1)))
        predicted_next = self.forward_model(torch.cat([phi, action], -1))
        return predicted_action, predicted_next, next_phi

    def predict(self, td: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`forward` on a transition's ``obs_key``, ``action_key`` and ``("next", obs_key)``."""
        obs, action = td.get(self.obs_key), td.get(self.action_key)
        return self(obs, action, td.get(("next", self.obs_key)))
