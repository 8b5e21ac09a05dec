"""Ensembles of Gaussian MLPs for the paper's dynamics and penalty predictors.

"Each of these ensembles consists of five neural networks, with three fully-connected layers of
128 hidden units each. All hidden layers are followed by ReLU activations." Each member outputs a
mean and a variance per output dimension; the members are differently seeded and run as one
batched module (weights ``[E, in, out]``), never as a python loop.

Inputs are normalised with running statistics. The dynamics models predict the normalised
*change* of their feature; :meth:`DynamicsModel.predict` maps the prediction back to a Gaussian
over the next feature value in the env's units (an exact affine change of variables), so the
surprise is the NLL of the true next state, as in the paper.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import pairwise

import torch
from tensordict import TensorDictBase
from torch import nn

from gentlerl import keys
from gentlerl.functional import gaussian_nll
from gentlerl.models.actor import _check_sizes
from gentlerl.models.layers import HeadLinear, RunningNorm


class GaussianEnsemble(nn.Module):
    """``ensemble_size`` MLPs ``in -> hidden... -> (mean, var)`` in one batched module.

    ``forward(x)`` takes ``[E, N, in]`` (a batch per member) and returns ``(mean, var)``, each
    ``[E, N, out]``; ``var = softplus(raw) + min_var`` keeps variances positive and floored.
    """

    def __init__(
        self,
        in_dim: int,
        out_dim: int,
        ensemble_size: int = 5,
        hidden: Sequence[int] = (128, 128, 128),
        *,
        min_var: float = 1e-4,
        seed: int = 0,
    ) -> None:
        super().__init__()
        _check_sizes(in_dim=in_dim, out_dim=out_dim, ensemble_size=ensemble_size, hidden=hidden)
        if min_var <= 0:
            raise ValueError(f"min_var must be > 0, got {min_var}")
        self.ensemble_size, self.out_dim, self.min_var = ensemble_size, out_dim, min_var
        gens = [torch.Generator().manual_seed(seed * 10_007 + e) for e in range(ensemble_size)]
        widths = [in_dim, *hidden]
        self.hidden = nn.ModuleList(
            HeadLinear(ensemble_size, i, o, generators=gens) for i, o in pairwise(widths)
        )
        self.head = HeadLinear(ensemble_size, widths[-1], 2 * out_dim, generators=gens)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if x.ndim != 3 or x.shape[0] != self.ensemble_size:
            raise ValueError(
                f"expected input [ensemble_size={self.ensemble_size}, N, in], got {tuple(x.shape)}"
            )
        for layer in self.hidden:
            x = torch.relu(layer(x))
        mean, raw_var = self.head(x).split(self.out_dim, dim=-1)
        return mean, nn.functional.softplus(raw_var) + self.min_var


def _members_input(x: torch.Tensor, ensemble_size: int, per_member: bool) -> torch.Tensor:
    """``[E, B.., d]`` (one batch per member) or ``[B.., d]`` (shared) to ``[E, N, d]``."""
    if per_member:
        return x.reshape(ensemble_size, -1, x.shape[-1])
    return x.reshape(1, -1, x.shape[-1]).expand(ensemble_size, -1, -1)


class _EnsembleModel(nn.Module):
    """Shared input handling: ``cat(observation, action)``, running-normalised."""

    def __init__(self, obs_dim: int, action_dim: int, obs_key: str, action_key: str) -> None:
        super().__init__()
        self.obs_key, self.action_key = obs_key, action_key
        self.obs_dim, self.action_dim = obs_dim, action_dim
        self.input_norm = RunningNorm(obs_dim + action_dim)

    def _inputs(self, td: TensorDictBase) -> torch.Tensor:
        parts = []
        for key, size in ((self.obs_key, self.obs_dim), (self.action_key, self.action_dim)):
            value = td.get(key, None)
            if value is None:
                raise KeyError(f"{type(self).__name__} reads {key!r}, which the batch lacks")
            if value.shape[-1] != size:
                raise ValueError(
                    f"{type(self).__name__} expects {key!r} of size {size}, got shape "
                    f"{tuple(value.shape)}"
                )
            parts.append(value)
        return torch.cat(parts, -1)


class DynamicsModel(_EnsembleModel):
    """One :class:`GaussianEnsemble` per state feature group (paper: joint_pos, joint_vel, touch).

    Args:
        feature_shapes: feature key -> its per-step shape, e.g. ``{"touch": (5, 3)}``.
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        feature_shapes: Mapping[str, Sequence[int]],
        ensemble_size: int = 5,
        hidden: Sequence[int] = (128, 128, 128),
        *,
        seed: int = 0,
        obs_key: str = keys.OBSERVATION,
        action_key: str = keys.ACTION,
    ) -> None:
        super().__init__(obs_dim, action_dim, obs_key, action_key)
        if not feature_shapes:
            raise ValueError("feature_shapes must name at least one feature")
        self.feature_shapes = {k: tuple(v) for k, v in feature_shapes.items()}
        self.ensemble_size = ensemble_size
        sizes = {k: int(torch.Size(v).numel()) for k, v in self.feature_shapes.items()}
        self.ensembles = nn.ModuleDict(
            {
                k: GaussianEnsemble(obs_dim + action_dim, d, ensemble_size, hidden, seed=seed + i)
                for i, (k, d) in enumerate(sizes.items())
            }
        )
        self.delta_norms = nn.ModuleDict({k: RunningNorm(d) for k, d in sizes.items()})

    def _flat(self, td: TensorDictBase, key: str | tuple) -> torch.Tensor:
        name = key if isinstance(key, str) else key[-1]
        return td.get(key).flatten(-len(self.feature_shapes[name]))

    def _deltas(self, td: TensorDictBase) -> dict[str, torch.Tensor]:
        return {k: self._flat(td, ("next", k)) - self._flat(td, k) for k in self.feature_shapes}

    @torch.no_grad()
    def update_normalizers(self, td: TensorDictBase) -> None:
        self.input_norm.update(self._inputs(td))
        for k, delta in self._deltas(td).items():
            self.delta_norms[k].update(delta)

    def nll(self, td: TensorDictBase, per_member: bool = True) -> torch.Tensor:
        """Training NLL of the normalised feature changes, summed over dims: ``[E, N]``."""
        x = _members_input(
            self.input_norm.normalize(self._inputs(td)), self.ensemble_size, per_member
        )
        total = 0.0
        for k, delta in self._deltas(td).items():
            target = _members_input(
                self.delta_norms[k].normalize(delta), self.ensemble_size, per_member
            )
            mean, var = self.ensembles[k](x)
            total = total + gaussian_nll(target, mean, var).sum(-1)
        return total

    def predict(self, td: TensorDictBase) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
        """Per-member Gaussians over each *next* feature, in env units: ``[E, *batch, dim]``."""
        batch = td.batch_size
        x = _members_input(self.input_norm.normalize(self._inputs(td)), self.ensemble_size, False)
        out = {}
        for k in self.feature_shapes:
            mean, var = self.ensembles[k](x)
            norm = self.delta_norms[k]
            current = self._flat(td, k).reshape(1, -1, mean.shape[-1])
            mean = current + norm.denormalize(mean)
            var = var * norm.std.pow(2)
            out[k] = (
                mean.reshape(self.ensemble_size, *batch, -1),
                var.reshape(self.ensemble_size, *batch, -1),
            )
        return out


class PenaltyModel(_EnsembleModel):
    """One :class:`GaussianEnsemble` predicting the impact penalty r^f from (state, action)."""

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        ensemble_size: int = 5,
        hidden: Sequence[int] = (128, 128, 128),
        *,
        seed: int = 0,
        obs_key: str = keys.OBSERVATION,
        action_key: str = keys.ACTION,
        penalty_key: str = keys.PENALTY,
    ) -> None:
        super().__init__(obs_dim, action_dim, obs_key, action_key)
        self.ensemble_size = ensemble_size
        self.penalty_key = penalty_key
        self.ensemble = GaussianEnsemble(obs_dim + action_dim, 1, ensemble_size, hidden, seed=seed)

    @torch.no_grad()
    def update_normalizers(self, td: TensorDictBase) -> None:
        self.input_norm.update(self._inputs(td))

    def nll(self, td: TensorDictBase, per_member: bool = True) -> torch.Tensor:
        """Training NLL of the observed penalty: ``[E, N]``."""
        x = _members_input(
            self.input_norm.normalize(self._inputs(td)), self.ensemble_size, per_member
        )
        target = _members_input(
            td.get(("next", self.penalty_key)).reshape(*td.batch_size, 1),
            self.ensemble_size,
            per_member,
        )
        mean, var = self.ensemble(x)
        return gaussian_nll(target, mean, var).sum(-1)

    def predict(self, td: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-member Gaussians over the penalty: ``[E, *batch, 1]``."""
        x = _members_input(self.input_norm.normalize(self._inputs(td)), self.ensemble_size, False)
        mean, var = self.ensemble(x)
        shape = (self.ensemble_size, *td.batch_size, 1)
        return mean.reshape(shape), var.reshape(shape)
