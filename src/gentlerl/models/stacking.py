"""Several seeds' parameters as one stack: built once, shared with each seed's modules, and
trained by one fused Adam whose state is read and written per seed.

:class:`~gentlerl.agent.Learner` and :class:`~gentlerl.rewards.model_step.ModelStep` update the
networks of S seeds (S = 1 for a plain run) as one step over parameters with a leading seed
axis; both hold a :class:`SeedStack`, the one place that stack and its optimiser are made. The
helpers below it make the stack (:func:`stack_parameters`), point each seed's own tensors at its
row of it so that the seed's modules act, evaluate and checkpoint with the updated values and no
copy (:func:`share_rows`; both at once: :func:`shared_stack`, which the r^sp re-scorer uses for
the seeds' target models), and convert the batched Adam's state to and from each seed's own
(:func:`optimizer_row`, :func:`stack_optimizer_rows`, :func:`load_optimizer_row`), so that a
seed's checkpoint is that of a run of its own.
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
    written by, the batched step's parameters. Refused (one line) when two seeds hold the same
    tensor: the same loss or model passed twice would train one module as two seeds."""
    if len(per_seed) != stacked.batch_size[0]:
        raise ValueError(
            f"share_rows: {len(per_seed)} seeds for a stack of {stacked.batch_size[0]} rows"
        )
    owner: dict[int, int] = {}
    for s, own in enumerate(per_seed):
        for key, tensor in own.items(True, True):
            first = owner.setdefault(id(tensor), s)
            if first != s:
                raise ValueError(
                    f"seeds {first} and {s} hold the same tensor {key!r}: each seed needs its "
                    "own networks (one loss passed twice?)"
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


#: What Adam keeps for each parameter (``max_exp_avg_sq`` only with ``amsgrad``).
ADAM_MOMENTS = ("exp_avg", "exp_avg_sq", "max_exp_avg_sq")


def optimizer_row_problem(optimizer: torch.optim.Optimizer, state: Any) -> str | None:
    """Why ``state`` (one seed's saved Adam state, :func:`optimizer_row`'s format) cannot go
    into a row of the batched ``optimizer``, or ``None``: its groups and parameters must be the
    optimiser's, each moment shaped and typed as its parameter's row, finite (the second moments
    >= 0), each step a finite count >= 0. Checked before anything is loaded: Adam's fused
    kernel given a moment of another shape writes past its buffer (an abort in native code)."""
    if not isinstance(state, Mapping):
        return f"is a {type(state).__name__}, not an optimiser state"
    saved, groups = state.get("state"), state.get("param_groups")
    if not isinstance(saved, Mapping) or not isinstance(groups, list | tuple):
        return "lacks its 'state' mapping or its 'param_groups' list"
    live = optimizer.param_groups
    if len(groups) != len(live):
        return f"holds {len(groups)} parameter group(s), the optimiser {len(live)}"
    params: dict[int, torch.Tensor] = {}
    for i, (group, own) in enumerate(zip(groups, live, strict=True)):
        ids = group.get("params") if isinstance(group, Mapping) else None
        if not isinstance(ids, list | tuple) or len(ids) != len(own["params"]):
            return f"parameter group {i} is not the optimiser's {len(own['params'])} parameters"
        if not all(isinstance(k, int) and not isinstance(k, bool) for k in ids):
            return f"parameter group {i} lists parameter ids that are not integers"
        params.update(zip(ids, own["params"], strict=True))
    if len(params) != sum(len(own["params"]) for own in live):
        return "its parameter groups list a parameter id twice"
    for index, entry in saved.items():
        if index not in params or not isinstance(entry, Mapping):
            return f"state {index!r} belongs to no parameter of the optimiser"
        if problem := _adam_entry_problem(entry, params[index]):
            return f"state {index} (parameter of shape {list(params[index].shape[1:])}): {problem}"
    return None


def _adam_entry_problem(entry: Mapping[str, Any], param: torch.Tensor) -> str | None:
    """Why one parameter's saved Adam entry is not one for a row of ``param`` ([S, ...])."""
    unknown = sorted(str(k) for k in entry if k not in ("step", *ADAM_MOMENTS))
    missing = [k for k in ("step", *ADAM_MOMENTS[:2]) if k not in entry]
    if unknown or missing:
        return f"holds {unknown} and lacks {missing}" if unknown else f"lacks {missing}"
    step = entry["step"]
    if isinstance(step, torch.Tensor):
        step = float(step) if step.ndim == 0 and not step.is_complex() else None
    if isinstance(step, bool) or not isinstance(step, int | float) or not 0 <= step < 2**53:
        return f"step {entry['step']!r} is not a finite count >= 0"
    for key in ADAM_MOMENTS:
        value = entry.get(key)
        if value is None:
            continue
        if not isinstance(value, torch.Tensor) or value.dtype != param.dtype:
            kind = value.dtype if isinstance(value, torch.Tensor) else type(value).__name__
            return f"{key} is {kind}, the parameter {param.dtype}"
        if value.shape != param.shape[1:]:
            return f"{key} has shape {list(value.shape)}, the parameter {list(param.shape[1:])}"
        if not bool(torch.isfinite(value).all()):
            return f"{key} holds a NaN or infinite value"
        if key != "exp_avg" and bool((value < 0).any()):
            return f"{key} holds a negative value (a second moment is >= 0)"
    return None


def load_optimizer_row(
    optimizer: torch.optim.Optimizer,
    state: Mapping[str, Any],
    seed: int,
    options: Mapping[str, Any],
) -> None:
    """One seed's own optimiser state (:func:`optimizer_row`'s format) loaded into row ``seed``
    of the batched ``optimizer`` (the other rows kept; all taken from ``state`` when nothing was
    stepped yet), run with the kernels ``options`` (e.g. fused, capturable) whatever it was saved
    with, and with ``optimizer``'s own hyperparameters (a learning rate changed since the state
    was saved applies from now on; the file's are not read).

    Raises:
        ValueError: :func:`optimizer_row_problem` refuses ``state`` (nothing was loaded).
    """
    if problem := optimizer_row_problem(optimizer, state):
        raise ValueError(f"seed {seed}'s saved optimiser state {problem}")
    state = _renumbered(state)
    num_seeds = optimizer.param_groups[0]["params"][0].shape[0]
    if optimizer.state:
        rows = [optimizer_row(optimizer.state_dict(), s) for s in range(num_seeds)]
    else:
        rows = [state] * num_seeds
    rows[seed] = state
    stacked = stack_optimizer_rows(rows)
    groups = [
        {**{k: v for k, v in own.items() if k != "params"}, **options, "params": saved["params"]}
        for saved, own in zip(stacked["param_groups"], optimizer.param_groups, strict=True)
    ]
    optimizer.load_state_dict({**stacked, "param_groups": groups})


def _renumbered(state: Mapping[str, Any]) -> dict[str, Any]:
    """``state`` with its parameter ids the positions of its parameters (as ``state_dict()``
    numbers them), whatever ids the file used."""
    ids = [k for group in state["param_groups"] for k in group["params"]]
    new = {old: i for i, old in enumerate(ids)}
    groups, start = [], 0
    for group in state["param_groups"]:
        groups.append({**group, "params": list(range(start, start + len(group["params"])))})
        start += len(group["params"])
    return {"state": {new[k]: v for k, v in state["state"].items()}, "param_groups": groups}


class SeedStack:
    """S seeds' parameters as one ``[S, ...]`` stack trained by one fused Adam, built once for the
    seeds asked for; the Learner's and the reward models' (S = 1 for a plain run).

    :attr:`params` is :func:`shared_stack` of ``per_seed`` (each seed's modules read and are
    written by its row, no copy). :attr:`optimizer` is one fused Adam over the stack's weights:
    one group at step size ``lr``, or one group per top-level entry of ``lr`` (in its order), the
    other entries frozen (target copies). Adam is elementwise and the rows disjoint, so it is S
    Adams: :meth:`row` is seed s's state as a run of its own saves it, :meth:`load_row` puts one
    back (checked first, :func:`optimizer_row_problem`). ``capturable``: for a CUDA graph.
    """

    def __init__(
        self,
        per_seed: Sequence[TensorDictBase],
        lr: float | Mapping[str, float],
        *,
        capturable: bool = False,
    ) -> None:
        self.params = shared_stack(per_seed)
        if isinstance(lr, Mapping):
            for name in self.params.keys() - lr.keys():
                self.params[name].apply_(lambda p: p.requires_grad_(False))
            parts = [(self.params[name], step) for name, step in lr.items()]
        else:
            parts = [(self.params, lr)]
        groups = [
            {
                "params": [p for p in td.values(True, True) if isinstance(p, nn.Parameter)],
                "lr": step,
            }
            for td, step in parts
        ]
        #: Adam's kernels (also for a state saved with others): fused, one per group.
        self.options = {"fused": True, "foreach": None, "capturable": capturable}
        self.optimizer = torch.optim.Adam(groups, **self.options)

    def descend(self, loss: torch.Tensor) -> None:
        """One Adam step of every seed down ``loss`` (their losses summed: the rows are
        disjoint, so each seed's gradient is its own loss's)."""
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.optimizer.step()

    def row(self, seed: int) -> dict[str, Any]:
        """Seed ``seed``'s Adam state, as a run of its own saves it (:func:`optimizer_row`)."""
        return optimizer_row(self.optimizer.state_dict(), seed)

    def load_row(self, state: Mapping[str, Any], seed: int) -> None:
        """Seed ``seed``'s saved Adam state (:meth:`row`'s format) into its row, run with
        :attr:`options` whatever it was saved with (:func:`load_optimizer_row`)."""
        load_optimizer_row(self.optimizer, state, seed, self.options)


def shared_stack(per_seed: Sequence[TensorDictBase]) -> TensorDictBase:
    """:func:`stack_parameters` of ``per_seed``, each seed's own tensors then views of its row
    (:func:`share_rows`)."""
    stacked = stack_parameters(per_seed)
    share_rows(stacked, per_seed)
    return stacked


def seed_stack(batches: Sequence[TensorDictBase]) -> TensorDictBase:
    """``[S, ...]``: one seed's batch as a view with a seed axis (no copy), several stacked."""
    return batches[0].unsqueeze(0) if len(batches) == 1 else torch.stack(list(batches))
