"""What a policy file's actor weights may be, checked before the actor is built: a file must not
be able to demand a huge allocation (``gentlerl evaluate`` runs files someone else shared)."""

from __future__ import annotations

import math
from typing import Any

import torch

from gentlerl.models import make_actor

#: The most parameters a policy file's actor may have (1 GiB of float32): several times the
#: largest actor a config builds from a hand's or a dm_control env's observation.
MAX_ACTOR_PARAMETERS = 2**28


def actor_weights_problem(weights: Any, sizes: tuple[Any, Any, tuple[int, ...]]) -> str | None:
    """Why ``weights`` are not those of the actor ``sizes`` (``obs_dim, action_dim, hidden``)
    describes, in one line, or ``None``.

    The weights must be dense tensors (an expanded, stride-0 view stands for far more memory
    than the file holds) named and shaped as that actor's, whose shapes are taken on the
    ``meta`` device (which allocates nothing) and held to :data:`MAX_ACTOR_PARAMETERS` in all:
    ``actor_hidden=[200000, 200000]`` or ``obs_dim=50_000_000`` is refused, not allocated.
    """
    obs_dim, action_dim, hidden = sizes
    for name, value in (("obs_dim", obs_dim), ("action_dim", action_dim)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            return f"{name}={value!r} must be an integer >= 1"
    if not isinstance(weights, dict) or not all(
        isinstance(v, torch.Tensor) for v in weights.values()
    ):
        return "its actor is not a mapping of weight tensors"
    strided = next((k for k, v in weights.items() if not v.is_contiguous()), None)
    if strided is not None:
        tensor = weights[strided]
        return (
            f"actor weight {strided} is not a dense tensor (shape {list(tensor.shape)}, strides "
            f"{list(tensor.stride())}: an expanded or strided view)"
        )
    described = f"obs_dim={obs_dim}, action_dim={action_dim}, network.actor_hidden={list(hidden)}"
    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in make_actor(*sizes).state_dict().items()}
    total = sum(math.prod(shape) for shape in expected.values())
    if total > MAX_ACTOR_PARAMETERS:
        return (
            f"its actor ({described}) would have {total:,} parameters, more than the "
            f"{MAX_ACTOR_PARAMETERS:,} a policy file may hold"
        )
    found = {k: tuple(v.shape) for k, v in weights.items()}
    if found != expected:
        diff = sorted(set(expected) ^ set(found)) or [
            f"{k} {found[k]} (expected {expected[k]})" for k in expected if found[k] != expected[k]
        ]
        return f"its actor weights do not match its config ({described}): {diff[0]}"
    return None
