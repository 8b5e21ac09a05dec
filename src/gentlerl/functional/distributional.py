"""Distributional RL functions for the D4PG learner (Bellemare 2017; Barth-Maron 2018)."""

from __future__ import annotations

import math

import torch

__all__ = ["categorical_projection", "categorical_support"]


def categorical_support(v_min: torch.Tensor, v_max: torch.Tensor, num_atoms: int) -> torch.Tensor:
    r"""Atoms :math:`z_j = v_{min} + j\,(v_{max} - v_{min}) / (N - 1)`, ``[..., num_atoms]``.

    ``v_min`` / ``v_max`` are tensors of any (matching) shape ``[...]``: one support per entry.
    """
    steps = torch.arange(num_atoms, device=v_min.device, dtype=v_min.dtype)
    return v_min.unsqueeze(-1) + (v_max - v_min).unsqueeze(-1) / (num_atoms - 1) * steps


def categorical_projection(
    next_probs: torch.Tensor,
    reward: torch.Tensor,
    discount: torch.Tensor,
    v_min: float | torch.Tensor,
    v_max: float | torch.Tensor,
) -> torch.Tensor:
    r"""Project the distribution of ``reward + discount * Z'`` onto the fixed support of ``Z'``.

    The C51 / D4PG target (Bellemare et al. 2017, Alg. 1; Barth-Maron et al. 2018, eq. 7): the atoms
    :math:`z_j = v_{min} + j\,\Delta z` of the next-state distribution are moved to
    :math:`\hat{T} z_j = \mathrm{clip}(r + d\, z_j, v_{min}, v_{max})` and each moved atom's mass
    :math:`p_j` is split between its two neighbouring atoms by linear interpolation:

    .. math::
        (\Phi \hat{T} Z)_i = \sum_j \left[1 - \frac{|\hat{T} z_j - z_i|}{\Delta z}\right]_0^1 p_j .

    The projection conserves mass, and the mean as long as no atom is clipped.

    Args:
        next_probs: ``[..., N]`` probabilities of the (target) next-state return distribution on
            ``linspace(v_min, v_max, N)``.
        reward: ``[...]`` (n-step) reward, broadcastable to ``next_probs.shape[:-1]``.
        discount: ``[...]`` bootstrap discount, already holding :math:`\gamma^n` and the
            not-terminated mask (0 for terminal transitions), broadcastable to
            ``next_probs.shape[:-1]``.
        v_min: lowest atom of the support: a float, or a tensor broadcastable to
            ``next_probs.shape[:-1]`` for a support per distribution (e.g. one per critic head).
            Float bounds are checked (finite, ``v_min < v_max``); tensor bounds are the caller's
            to check (see :func:`_check_float_support`).
        v_max: highest atom of the support, same shapes as ``v_min``.

    Returns:
        ``[..., N]`` projected target probabilities (no gradient flows through the atom indices).

    Raises:
        ValueError: a NaN ``reward`` or ``discount`` (on the CPU; an infinite one is clipped to
            the support's end like any other).
    """
    num_atoms = next_probs.shape[-1]
    if num_atoms < 2:
        raise ValueError(
            "next_probs needs at least 2 atoms on its last dim, "
            f"got shape {tuple(next_probs.shape)}"
        )
    _check_float_support(v_min, v_max)
    v_min = torch.as_tensor(v_min, dtype=next_probs.dtype, device=next_probs.device).unsqueeze(-1)
    v_max = torch.as_tensor(v_max, dtype=next_probs.dtype, device=next_probs.device).unsqueeze(-1)
    delta = (v_max - v_min) / (num_atoms - 1)
    support = v_min + delta * torch.arange(num_atoms, device=delta.device, dtype=delta.dtype)
    moved = reward.unsqueeze(-1) + discount.unsqueeze(-1) * support
    position = (torch.clamp(moved, v_min, v_max) - v_min) / delta
    position, probs = torch.broadcast_tensors(position, next_probs)
    lower = position.floor().clamp(0, num_atoms - 1)
    # When an atom lands exactly on the grid its upper weight is 0: the lower atom keeps its mass.
    upper_weight = position - lower
    upper = (lower + 1).clamp(max=num_atoms - 1)
    index = torch.cat([lower, upper], -1).long()
    mass = torch.cat([probs * (1.0 - upper_weight), probs * upper_weight], -1)
    try:
        return torch.zeros_like(probs).scatter_add_(-1, index, mass)
    except RuntimeError as error:  # a NaN position casts to index -2**63 (no sync to test it first)
        if "out of bounds" not in str(error):
            raise
        raise ValueError(
            "categorical_projection: a reward or discount is NaN (its moved atom has no index on "
            "the support); check the batch's rewards"
        ) from error


def _check_float_support(v_min: float | torch.Tensor, v_max: float | torch.Tensor) -> None:
    """``ValueError`` unless float bounds are finite with ``v_min < v_max``.

    Tensor bounds are not checked: reading them would wait for their device (a host sync on every
    update, and a graph break under ``torch.compile``); the critic checks its supports when built.
    """
    if isinstance(v_min, torch.Tensor) or isinstance(v_max, torch.Tensor):
        return
    if not (math.isfinite(v_min) and math.isfinite(v_max) and v_min < v_max):
        raise ValueError(f"need finite v_min < v_max, got v_min={v_min}, v_max={v_max}")
