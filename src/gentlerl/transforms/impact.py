"""``ImpactPenalty``: impact per sensor site (eq. 1) and the impact penalty r^f (eq. 4);
``ExcessPenalty``: Method IV's cost, the impact above a tolerance."""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase
from torchrl.data import Composite

from gentlerl import keys
from gentlerl.functional import excess_cost, impact, impact_penalty
from gentlerl.functional.constraint import check_tolerance
from gentlerl.transforms.base import TransitionTransform, check_lam


class ImpactPenalty(TransitionTransform):
    r"""Writes ``impact`` :math:`m^i_t = \sum_c \max(0, f^{i,c}_{t+1} - f^{i,c}_t)` ``[n_sites]`` and
    ``penalty`` :math:`r^f_t = -\sum_i (1 - a_\lambda(m^i_t))\, m^i_t` ``[1]`` under ``"next"``.

    Works with any force key shaped ``[..., n_sites, n_channels]`` (the hand env's ``touch``
    ``[5, 3]``). After a reset the previous force is the reset observation, so the first step has
    no spurious impact.

    Args:
        lam: :math:`\lambda = [\lambda_1, \lambda_2]` of the acceptability sigmoid (paper: [2, 2]).
        unit: the force unit :math:`u` the penalty reads impacts in, :math:`r^f` of
            :math:`m / u` (1: newtons, the paper; the tolerance rule's
            :func:`~gentlerl.functional.tolerance_unit`). ``impact`` is written in N either way.
        in_keys: ``[force_key]``; out_keys: ``[impact_key, penalty_key]``.

    Examples:
        >>> from tensordict import TensorDict
        >>> td = TensorDict({"touch": torch.zeros(5, 3),
        ...                  "next": {"touch": torch.tensor([[1.0, 0, 0]] + [[0.0] * 3] * 4)}})
        >>> out = ImpactPenalty()(td)
        >>> round(out["next", "penalty"].item(), 4)
        -0.1192
    """

    scalar_out_keys = (keys.PENALTY,)

    def __init__(
        self,
        lam: tuple[float, float] = (2.0, 2.0),
        *,
        unit: float = 1.0,
        in_keys: list[str] | None = None,
        out_keys: list[str] | None = None,
    ) -> None:
        in_keys = in_keys or [keys.TOUCH]
        out_keys = out_keys or [keys.IMPACT, keys.PENALTY]
        if len(in_keys) != 1 or len(out_keys) != 2:
            raise ValueError(
                f"ImpactPenalty takes one force key and writes [impact, penalty]; got in_keys="
                f"{in_keys}, out_keys={out_keys}"
            )
        self.lam = check_lam("ImpactPenalty", lam)
        if not (math.isfinite(unit) and unit > 0):
            raise ValueError(f"ImpactPenalty: unit must be a finite force > 0, got {unit!r}")
        self.unit = float(unit)
        super().__init__(in_keys=in_keys, out_keys=out_keys)
        self.scalar_out_keys = (out_keys[1],)

    def observation_out_shapes(self, observation_spec: Composite) -> dict[str, tuple[int, ...]]:
        force_spec = self.read(observation_spec, self.in_keys[0])
        force_shape = force_spec.shape[len(observation_spec.shape) :]
        return {self.out_keys[0]: tuple(force_shape[:-1])}

    def reset_outputs(self, tensordict_reset: TensorDictBase) -> dict[str, torch.Tensor]:
        force = self.read(tensordict_reset, self.in_keys[0])
        return {self.out_keys[0]: force.new_zeros(force.shape[:-1])}

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        force, next_force = (self.read(td, self.in_keys[0]) for td in (tensordict, next_tensordict))
        if force.shape != next_force.shape or force.ndim < 2:
            raise ValueError(
                f"ImpactPenalty: {self.in_keys[0]!r} must be [..., n_sites, n_channels] at both "
                f"steps, got {tuple(force.shape)} and {tuple(next_force.shape)}"
            )
        if not (force.is_floating_point() and bool((force + next_force).isfinite().all())):
            # one reduction on the hot path; the checks that name the culprit only on a failure
            _check_force(self.in_keys[0], force, "s_t")
            _check_force(self.in_keys[0], next_force, "s_t+1")
        m = impact(force, next_force)
        penalty = impact_penalty(m / self.unit, *self.lam).unsqueeze(-1)
        if not bool(torch.isfinite(penalty).all()):  # finite forces whose impacts overflow
            raise NonFiniteForceError(
                f"ImpactPenalty: {self.in_keys[0]!r} forces up to {next_force.abs().max().item():.3g}"
                f" overflow the penalty in {penalty.dtype} (a force unit off by orders of magnitude?"
                " env.force_scale reads another unit)"
            )
        return {self.out_keys[0]: m, self.out_keys[1]: penalty}


class NonFiniteForceError(ValueError):
    """A force reading is NaN or infinite (the rewards and models would all become NaN)."""


def _check_force(key: object, force: torch.Tensor, step: str) -> None:
    """A floating-point force, finite everywhere: else one line naming the key, the ``step``
    (``"s_t"`` or ``"s_t+1"``) and where (the index over the leading dims, site, channel)."""
    if not force.is_floating_point():
        raise ValueError(
            f"ImpactPenalty: {key!r} must be a floating-point force, got {force.dtype}"
        )
    finite = torch.isfinite(force)
    if not bool(finite.all()):
        index = (~finite).nonzero()[0].tolist()
        value = force[tuple(index)].item()
        raise NonFiniteForceError(
            f"ImpactPenalty: {key!r} holds a non-finite force ({value}) at {step}, index "
            f"{index[:-2] or '()'}, site {index[-2]}, channel {index[-1]}"
        )


class ExcessPenalty(TransitionTransform):
    r"""Writes ``excess_penalty`` :math:`-c_t` ``[1]`` under ``"next"``: Method IV's cost, the
    impact above the tolerance in tolerances, capped at 1 a step
    (:func:`~gentlerl.functional.excess_cost`), as a reward its own critic head maximises.

    Reads the ``impact`` that :class:`ImpactPenalty` writes (so it comes after it). An episode's
    cost :math:`J = \sum_t c_t` is what a Lagrangian holds under a limit
    (:class:`~gentlerl.rewards.CostLagrangian`).

    Args:
        tolerance: :math:`T`, in the unit of ``impact``.
        in_keys: ``[impact_key]``; out_keys: ``[penalty_key]``.

    Examples:
        >>> from tensordict import TensorDict
        >>> td = TensorDict({"next": {"impact": torch.tensor([3.0, 1.0, 0.0])}})
        >>> ExcessPenalty(2.0)(td)["next", "excess_penalty"]
        tensor([-0.5000])
    """

    def __init__(
        self,
        tolerance: float,
        *,
        in_keys: list[str] | None = None,
        out_keys: list[str] | None = None,
    ) -> None:
        in_keys = in_keys or [keys.IMPACT]
        out_keys = out_keys or [keys.EXCESS_PENALTY]
        if len(in_keys) != 1 or len(out_keys) != 1:
            raise ValueError(
                f"ExcessPenalty reads one impact key and writes one penalty; got in_keys="
                f"{in_keys}, out_keys={out_keys}"
            )
        self.tolerance = check_tolerance(tolerance)
        super().__init__(in_keys=in_keys, out_keys=out_keys)
        self.scalar_out_keys = (out_keys[0],)

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        m = self.read(next_tensordict, self.in_keys[0])
        return {self.out_keys[0]: -excess_cost(m, self.tolerance).unsqueeze(-1)}
