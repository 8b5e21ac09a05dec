"""What stops a run: a NaN / inf reward, loss or force reading (before it is saved), and a fault
outside the run (a collector process killed), each saying what the run left to resume from."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch

from gentlerl.transforms.impact import NonFiniteForceError

if TYPE_CHECKING:
    from tensordict import TensorDictBase
    from torchrl.envs import Transform


class NonFiniteError(RuntimeError):
    """A reward or loss became NaN or infinite; training stopped before saving it."""


def stop_if_not_finite(values: Mapping[str, Any], where: str, checkpoint: Path) -> None:
    """Raise :class:`NonFiniteError` naming the first NaN / inf value of ``values`` and ``where``
    (the frames) it appeared; ``values`` maps names to floats or tensors (all elements checked).
    """
    for name, value in values.items():
        finite = (
            bool(torch.isfinite(value).all())
            if isinstance(value, torch.Tensor)
            else math.isfinite(value)
        )
        if not finite:
            raise NonFiniteError(
                f"non-finite {name} at {where}: training stopped; {checkpoint_note(checkpoint)} "
                "(a NaN / inf reward or loss: check the env's forces, the config's numbers, the "
                "learning rates)"
            )


def rewarded(
    transform: Transform,
    batch: TensorDictBase,
    reward_keys: list[str],
    frames: int,
    checkpoint: Path,
) -> TensorDictBase:
    """``transform(batch)``: the reward transforms applied to a collected batch that follows the
    first ``frames``; a NaN / inf force reading, or a non-finite ``("next", key)`` reward of
    ``reward_keys``, stops training (:class:`NonFiniteError`)."""
    where = f"frames {frames + 1}-{frames + batch.numel()}"
    try:
        batch = transform(batch)
    except NonFiniteForceError as err:
        raise NonFiniteError(
            f"non-finite force at {where}: training stopped; {checkpoint_note(checkpoint)} "
            f"({err}; check the env's force sensor)"
        ) from None
    stop_if_not_finite({key: batch.get(("next", key)) for key in reward_keys}, where, checkpoint)
    return batch


def checkpoint_note(checkpoint: Path) -> str:
    """What a stopped run left to resume from: its last checkpoint, or none yet."""
    if checkpoint.exists():
        return f"the last checkpoint {checkpoint} is intact"
    return "no checkpoint was written yet"


def resumable_fault(err: OSError, checkpoint: Path) -> OSError:
    """``err`` (a fault outside the run: a collector process killed) saying what the run left
    (:func:`checkpoint_note`) and that ``resume=auto`` continues it."""
    return type(err)(f"{err}; {checkpoint_note(checkpoint)}: rerun with resume=auto to continue")
