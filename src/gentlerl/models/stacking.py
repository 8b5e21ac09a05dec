"""Several seeds' parameters as one stack: built, shared with each seed's modules, and the
batched optimiser's state read and written per seed.

:class:`~gentlerl.agent.Learner` and :class:`~gentlerl.rewards.model_step.ModelStep` update the
networks of S seeds (S = 1 for a plain run) as one step over parameters with a leading seed
axis. These helpers make that stack (:func:`stack_parameters`), point each seed's own tensors at
its row of it so that the seed's modules act, evaluate and checkpoint with the updated values
and no copy (:func:`share_rows`), and convert the batched Adam's state to and from each seed's
own (:func:`optimizer_row`, :func:`stack_optimizer_rows`), so that a seed's checkpoint is that
of a run of its own.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import torch
from tensordict import TensorDictBase
from torch import nn


def stack_parameters(per_seed: Sequence[TensorDictBase]) -> TensorDictBase:
    """``[S, ...]`` copies of the seeds' tensors (one structure), as ``nn.Parameter`` where the
    first seed's entry is one (weights) and as plain tensors elsewhere (normaliser statistics,
    target copies marked frozen stay parameters without gradient)."""
    if not per_seed:
        raise ValueError("stack_parameters needs at least one seed's parameters, got 0")
    trainable = {_path(k) for k, v in per_seed[0].items(True, True) if isinstance(v, nn.Parameter)}
    stacked = torch.stack([td.data for td in per_seed]).clone()
    return stacked.named_apply(
        lambda key, t: nn.Parameter(t) if _path(key) in trainable else t,
        nested_keys=True,
        filter_empty=False,
    )


def _path(key: str | tuple[str, ...]) -> tuple[str, ...]:
    """A tensordict key as a tuple (a top-level key comes as a string)."""
    return (key,) if isinstance(key, str) else key


@torch.no_grad()
def share_rows(stacked: TensorDictBase, per_seed: Sequence[TensorDictBase]) -> None:
    """Point every tensor of seed s at row s of ``stacked`` (``tensor.data = row``): the same
    tensor objects (so modules and optimisers holding them stay valid) now read, and are
    written by, the batched step's parameters."""
    if len(per_seed) != stacked.batch_size[0]:
        raise ValueError(
            f"share_rows: {len(per_seed)} seeds for a stack of {stacked.batch_size[0]} rows"
        )
    for s, own in enumerate(per_seed):
        for key, tensor in own.items(True, True):
            tensor.data = stacked.get(key).data[s]


def optimizer_row(state: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """Row ``seed`` of a batched optimiser's ``state_dict()``: the state dict of one seed's own
    optimiser over the same parameter groups (Adam's moments row ``seed``, its step count as
    is), the format a run of its own saves and resumes."""
    rows = {
        index: {k: (v[seed].clone() if k != "step" and v.ndim else v.clone()) for k, v in s.items()}
        for index, s in state["state"].items()
    }
    return {"state": rows, "param_groups": copy.deepcopy(state["param_groups"])}


def stack_optimizer_rows(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The batched optimiser's ``state_dict()`` made of each seed's own (:func:`optimizer_row`'s
    inverse): moments stacked on a leading seed axis, the first seed's step count and groups.

    Raises:
        ValueError: no rows, or rows over different parameters.
    """
    if not rows:
        raise ValueError("stack_optimizer_rows needs at least one seed's optimiser state, got 0")
    first = rows[0]["state"]
    for s, row in enumerate(rows):
        if row["state"].keys() != first.keys():
            raise ValueError(
                f"stack_optimizer_rows: seed {s}'s optimiser state holds parameters "
                f"{sorted(row['state'])}, seed 0's {sorted(first)}"
            )
    stacked = {
        index: {
            k: (
                v.clone()
                if k == "step" or not v.ndim
                else torch.stack([r["state"][index][k] for r in rows])
            )
            for k, v in state.items()
        }
        for index, state in first.items()
    }
    return {"state": stacked, "param_groups": copy.deepcopy(rows[0]["param_groups"])}


def over_seeds(fn: Callable[..., Any], num_seeds: int) -> Callable[..., Any]:
    """``fn(batch, params)`` of one seed run over a leading seed axis of both: one
    ``torch.vmap`` for several seeds (each its own random draws), a plain call on row 0 for one
    (vmap's batching rules would only add copies there); the outputs (a tensor, a tensordict or
    a tuple of them) carry the seed axis either way."""
    if num_seeds > 1:
        return torch.vmap(fn, (0, 0), randomness="different")

    def one_seed(batch: TensorDictBase, params: TensorDictBase) -> Any:
        out = fn(batch[0], params[0])
        return tuple(o.unsqueeze(0) for o in out) if isinstance(out, tuple) else out.unsqueeze(0)

    return one_seed


def load_optimizer_row(
    optimizer: torch.optim.Optimizer,
    state: Mapping[str, Any],
    seed: int,
    options: Mapping[str, Any],
) -> None:
    """One seed's own optimiser state (:func:`optimizer_row`'s format) loaded into row ``seed``
    of the batched ``optimizer`` (the other rows kept; all taken from ``state`` when nothing was
    stepped yet), run with the kernels ``options`` (e.g. fused, capturable) whatever it was saved
    with."""
    num_seeds = optimizer.param_groups[0]["params"][0].shape[0]
    if optimizer.state:
        rows = [optimizer_row(optimizer.state_dict(), s) for s in range(num_seeds)]
    else:
        rows = [state] * num_seeds
    rows[seed] = state
    stacked = stack_optimizer_rows(rows)
    groups = [{**g, **options} for g in stacked["param_groups"]]
    optimizer.load_state_dict({**stacked, "param_groups": groups})


def seed_stack(batches: Sequence[TensorDictBase]) -> TensorDictBase:
    """``[S, ...]``: one seed's batch as a view with a seed axis (no copy), several stacked."""
    return batches[0].unsqueeze(0) if len(batches) == 1 else torch.stack(list(batches))
