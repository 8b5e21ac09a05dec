"""Global random state: seed it at the start of a run, save and restore it with checkpoints."""

from __future__ import annotations

import random
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

if TYPE_CHECKING:
    from gentlerl.training.seed_run import SeedRun


def seed_everything(seed: int) -> None:
    """Seed python's, numpy's and torch's global generators."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def rng_state() -> dict[str, Any]:
    """The three global generators' states (for a checkpoint)."""
    return {
        "python": random.getstate(),
        "numpy": np.random.get_state(),
        "torch": torch.get_rng_state(),
    }


def set_rng_state(state: dict[str, Any]) -> None:
    """Inverse of :func:`rng_state`."""
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])


@contextmanager
def own_stream(run: SeedRun) -> Iterator[None]:
    """Within: the process's generators hold ``run.rng`` (a :func:`rng_state`); after: the state
    they reached is kept in ``run.rng``. Each seed of a group draws from its own continuing
    stream, as it would alone, whatever the other seeds draw in between."""
    set_rng_state(run.rng)
    try:
        yield
    finally:
        run.rng = rng_state()
