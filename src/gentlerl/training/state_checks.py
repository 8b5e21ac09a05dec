"""What a checkpoint's saved replay must be before a run resumes from it: the checks that turn a
crafted or damaged file into one line naming it, instead of an index error deep in the sampler."""

from __future__ import annotations

from typing import Any

import torch


def replay_state_problem(state: dict[str, Any], capacity: int) -> str | None:
    """Why a saved replay cannot be loaded into a buffer of ``capacity`` rows, or ``None``:
    rows past the capacity, an entry that is not dense (a crafted stride-0 row) or not finite,
    a priority tree with a negative or non-finite value, a negative writer cursor or count."""
    data = state.get("_storage", {}).get("data")
    if data is not None:
        if len(data) > capacity:
            return f"its replay holds {len(data)} rows, over the buffer's {capacity}"
        for key, value in data.items(True, True):
            if any(
                step == 0 and size > 1
                for step, size in zip(value.stride(), value.shape, strict=True)
            ):
                return f"replay entry {key} is not dense (stride {value.stride()})"
            if value.is_floating_point() and not bool(torch.isfinite(value).all()):
                return f"replay entry {key} holds a NaN or infinite value"
    for name, tree in state.get("_sampler", {}).items():
        values = getattr(tree, "values", None)
        if isinstance(values, torch.Tensor):  # a min tree's empty slots hold +inf
            bad = torch.isnan(values) | (values < 0)
            if getattr(tree, "reduce", None) == "sum":
                bad |= torch.isinf(values)
            if bool(bad.any()):
                return f"replay priorities ({name}) hold a negative, NaN or infinite value"
    writer = state.get("_writer", {})
    if any(isinstance(v, int) and v < 0 for v in writer.values()):
        return f"replay writer counters {writer} are negative"
    return None
