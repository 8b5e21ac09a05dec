"""Several seeds' parameters as one stack: built, shared with each seed's modules, and the
batched optimiser's state read back per seed.

:class:`~gentlerl.agent.seeds.SeedBatchedLearner` and
:class:`~gentlerl.rewards.model_step.SeedBatchedModelStep` update S seeds' networks as one
``torch.vmap``-ed step over parameters with a leading seed dimension. These helpers make that
stack (:func:`stack_parameters`), point each seed's own tensors at its row of it so that the
seed's modules act, evaluate and checkpoint with the updated values and no copy
(:func:`share_rows`), and give each seed's own optimiser its row of the batched Adam's state
(:func:`optimizer_rows`), so that a seed's checkpoint resumes on its own.
"""

from __future__ import annotations

from collections.abc import Sequence

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


@torch.no_grad()
def optimizer_rows(
    batched: torch.optim.Optimizer, singles: Sequence[torch.optim.Optimizer]
) -> None:
    """Give each seed's own optimiser (same parameter groups, in the same order) its row of the
    batched optimiser's state: Adam's moments row s, its step count as is."""
    for s, single in enumerate(singles):
        pairs = zip(batched.param_groups, single.param_groups, strict=True)
        for group, own in pairs:
            for p, q in zip(group["params"], own["params"], strict=True):
                state = batched.state.get(p)
                if state:
                    single.state[q] = {
                        k: (v[s].clone() if k != "step" and v.ndim else v.clone())
                        for k, v in state.items()
                    }
