"""The categorical n-step TD(0) target of the multi-head D4PG critics (its value estimator)."""

from __future__ import annotations

import torch

from gentlerl.functional import categorical_projection


class CategoricalTD0:
    r"""Target distribution :math:`\Phi\,(R + \gamma^n (1 - \mathrm{cut})\, Z')` per head.

    The D4PG critic target (Barth-Maron et al. 2018, eq. 7): the next-state distribution
    :math:`Z'` of each head, moved by the head's n-step return :math:`R` and discount, projected
    back on that head's support. Built by ``MultiHeadD4PGLoss.make_value_estimator``.

    Args:
        gamma: discount per step; an n-step transition is discounted by ``gamma ** n``.
    """

    def __init__(self, gamma: float = 0.99) -> None:
        if not 0.0 <= gamma <= 1.0:
            raise ValueError(f"gamma must be in [0, 1], got {gamma}")
        self.gamma = float(gamma)

    def target(
        self,
        next_logits: torch.Tensor,
        next_atoms: torch.Tensor,
        reward: torch.Tensor,
        steps: torch.Tensor,
        cut: torch.Tensor,
    ) -> torch.Tensor:
        """``[B, K, atoms]`` projected targets.

        Args:
            next_logits, next_atoms: ``[B, K, atoms]`` of the target critics at ``s_{t+n}``.
            reward: ``[B, K]`` n-step returns of the heads.
            steps: ``[B, 1]`` n of each transition.
            cut: ``[B, K]`` bool, true where a head's bootstrap is cut (termination).
        """
        discount = self.gamma ** steps.to(reward.dtype) * (~cut).to(reward.dtype)
        v_min, v_max = next_atoms[..., 0], next_atoms[..., -1]
        return categorical_projection(next_logits.softmax(-1), reward, discount, v_min, v_max)
