"""The steps behind each n-step transition, so that model-based rewards can be recomputed.

``MultiStepTransform`` stores :math:`\\sum_{j<k} \\gamma^j r_{t+j}` and forgets the steps it summed.
A reward computed from a learned model (penalty surprise, eq. 8) is then frozen at the model of
the moment it was collected: a bonus for a contact the model has learned since never fades.
:func:`nstep_windows` keeps, for every stored transition, the ``n`` raw steps of its window (the
inputs the model needs), and :func:`nstep_return` sums a recomputed per-step reward over them
exactly as ``MultiStepTransform`` summed the stored one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

if TYPE_CHECKING:
    from torchrl.envs import Transform

#: Entry of a stored transition holding its window: a tensordict of batch ``[..., n]``.
WINDOW = "window"


def nstep_windows(steps: TensorDictBase, n_steps: int, count: int) -> TensorDictBase:
    """The first ``count`` length-``n_steps`` windows along the last (time) dim of ``steps``.

    Window ``i`` holds steps ``i .. i + n_steps - 1``: ``steps`` ``[..., T]`` gives
    ``[..., count, n_steps]`` (``count <= T - n_steps + 1``). Which of a window's steps count is
    :func:`nstep_return`'s business (the episode may end inside it).
    """
    *batch, time = steps.batch_size
    if n_steps < 1 or not 0 <= count <= time - n_steps + 1:
        raise ValueError(
            f"need n_steps >= 1 and 0 <= count <= T - n_steps + 1, got n_steps={n_steps}, "
            f"count={count}, T={time}"
        )
    dim = len(batch)

    def unfold(x: torch.Tensor) -> torch.Tensor:
        return x.unfold(dim, n_steps, 1).movedim(-1, dim + 1)[
            (slice(None),) * dim + (slice(count),)
        ]

    return steps.apply(unfold, batch_size=[*batch, count, n_steps])


def nstep_return(
    rewards: torch.Tensor, steps_to_next_obs: torch.Tensor, gamma: float
) -> torch.Tensor:
    r"""The n-step return of per-step rewards over each window's first ``k`` steps.

    .. math:: R_t = \sum_{j=0}^{k_t - 1} \gamma^j r_{t+j}

    with :math:`k_t` = ``steps_to_next_obs`` (``MultiStepTransform``'s: ``n``, or fewer where the
    episode ends inside the window).

    Args:
        rewards: ``[..., n, 1]`` per-step rewards of each window.
        steps_to_next_obs: ``[...]`` or ``[..., 1]`` steps counted (``1 <= k <= n``).
        gamma: the discount.

    Returns:
        ``[..., 1]``.
    """
    n = rewards.shape[-2]
    j = torch.arange(n, device=rewards.device)
    k = steps_to_next_obs.reshape(*rewards.shape[:-2], 1)
    weights = torch.where(j < k, gamma ** j.to(rewards.dtype), torch.zeros((), dtype=rewards.dtype))
    return (weights.unsqueeze(-1) * rewards).sum(-2)


def rescore_windows(
    transforms: Sequence[Transform], batch: TensorDictBase, gamma: float, device: torch.device
) -> dict[str, float]:
    r"""Score each sampled transition's window again with ``transforms`` (their ``compute``,
    models on ``device``) and replace ``("next", out_key)`` by the :func:`nstep_return` of it.

    Returns ``<out_key>_per_contact_step``: the mean rescored reward over the counted window
    steps with a penalty (``("next", penalty_key)`` < 0; absent when the batch has none), the
    number that falls when a model learns what it pays surprise for.
    """
    window = window_of(batch)
    flat, steps = window.reshape(-1).to(device), batch.get("steps_to_next_obs")
    metrics: dict[str, float] = {}
    for t in transforms:
        key = t.out_keys[0]
        per_step = t.compute(flat, flat.get("next"))[key].reshape(*window.batch_size, 1)
        per_step = per_step.to(steps.device)  # the models' device -> the batch's
        batch.set(("next", key), nstep_return(per_step, steps, gamma))
        total, count = contact_step_sum(per_step, window.get(("next", t.penalty_key)), steps)
        if count > 0:  # a batch without contact says nothing about the bonus's size
            metrics[f"{key}_per_contact_step"] = (total / count).item()
    return metrics


def window_of(batch: TensorDictBase) -> TensorDictBase:
    """The sampled transitions' windows of raw steps (``batch[WINDOW]``), or a ``KeyError``
    saying where they come from."""
    window = batch.get(WINDOW, None)
    if window is None:
        raise KeyError(
            "rescore_surprise needs each transition's window of steps ('window'), written "
            "by an NStepWriter given window_keys=IntrinsicRewards.window_keys"
        )
    return window


def contact_step_sum(
    per_step: torch.Tensor, penalty: torch.Tensor, steps_to_next_obs: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The sum of ``per_step`` ``[..., B, n, 1]`` over the window steps that count (the first
    ``steps_to_next_obs``) and have contact (``penalty`` < 0), and how many there are: ``[...]``
    each (a NaN reward stays in the sum)."""
    n = per_step.shape[-2]
    counted = torch.arange(n, device=per_step.device) < steps_to_next_obs.reshape(
        *per_step.shape[:-2], 1
    )
    counted = (penalty < 0) & counted.unsqueeze(-1)
    total = torch.where(counted, per_step, torch.zeros((), dtype=per_step.dtype))
    return total.sum((-3, -2, -1)), counted.sum((-3, -2, -1))
