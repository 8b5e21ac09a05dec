"""TorchRL's ``PrioritizedSampler`` with its priority trees in plain torch.

The TorchRL 0.14.1 wheel's C++ segment trees (``torchrl._torchrl``) do not load against the pinned
torch 2.13.0 CPU wheel (undefined symbol), and TorchRL then refuses to build a
``PrioritizedSampler``. :class:`TorchPrioritizedSampler` keeps *all* of TorchRL's sampler logic
(alpha/beta, importance weights, ``update_priority``, state dicts, schedulers) and swaps only the two
trees for :class:`FlatPriorityTree`: a flat tensor whose range sums/minima are vectorised
reductions and whose prefix-sum search is ``cumsum`` + ``searchsorted`` over the entries written
so far. Each sample costs O(entries written) in C-speed torch ops (about 1 ms for 1M), no python
loop: a paper-scale buffer (1M slots) holding its first 25k transitions scans 25k.

No torchrl wheel on the package registry loads against that torch build (each 0.12.0–0.14.1
wheel misses torch C++ symbols: 0.14.x was built against torch 2.14, 0.12–0.13 against older
releases), so TorchRL's ``Failed to import torchrl C++ binaries`` warning, which its sampler logs
at construction, says nothing a user of this sampler can act on: it is dropped here, and only
here (see :func:`_without_extension_warning`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np
import torch
from torchrl._extension import EXTENSION_WARNING
from torchrl._utils import logger as torchrl_logger
from torchrl.data import PrioritizedSampler


class FlatPriorityTree:
    """The subset of TorchRL's ``Sum/MinSegmentTree`` interface the sampler uses, on a flat tensor."""

    def __init__(self, capacity: int, reduce: Literal["sum", "min"], dtype: torch.dtype) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        if reduce not in ("sum", "min"):
            raise ValueError(f"reduce must be 'sum' or 'min', got {reduce!r}")
        self.reduce = reduce
        self.neutral = 0.0 if reduce == "sum" else float("inf")
        self.values = torch.full((capacity,), self.neutral, dtype=dtype)

    @property
    def values(self) -> torch.Tensor:
        """The ``[capacity]`` entries (the neutral value where none was written)."""
        return self._values

    @values.setter
    def values(self, values: torch.Tensor) -> None:
        self._values = values
        written = (values != self.neutral).nonzero()
        #: One past the highest entry written: the prefix-sum search reads no further.
        self.extent = int(written[-1]) + 1 if len(written) else 0

    @staticmethod
    def _index(index: int | np.ndarray | torch.Tensor) -> torch.Tensor:
        return torch.as_tensor(index, dtype=torch.long)

    def __getitem__(self, index: int | np.ndarray | torch.Tensor) -> torch.Tensor:
        return self.values[self._index(index)]

    def __setitem__(
        self, index: int | np.ndarray | torch.Tensor, value: float | np.ndarray | torch.Tensor
    ) -> None:
        index = self._index(index)
        self.values[index] = torch.as_tensor(value, dtype=self.values.dtype)
        if index.numel():
            self.extent = max(self.extent, int(index.max()) + 1)

    def query(self, left: int, right: int) -> float:
        """Sum (or min) of the entries in ``[left, right)``."""
        window = self.values[int(left) : int(right)]
        return float(window.sum() if self.reduce == "sum" else window.min())

    def scan_lower_bound(self, mass: np.ndarray | torch.Tensor) -> torch.Tensor:
        """Smallest index whose inclusive prefix sum exceeds each ``mass`` (``extent`` where none
        does among the entries written; the sampler clamps it into the storage)."""
        cumulative = self.values[: self.extent].cumsum(0)
        mass = torch.as_tensor(mass, dtype=cumulative.dtype)
        return torch.searchsorted(cumulative, mass, right=True)


class _DropRecord(logging.Filter):
    """Drops the log records whose message is exactly ``message``."""

    def __init__(self, message: str) -> None:
        super().__init__()
        self.message = message

    def filter(self, record: logging.LogRecord) -> bool:
        return record.getMessage() != self.message


@contextlib.contextmanager
def _without_extension_warning() -> Iterator[None]:
    """TorchRL's logger without its C++-extension warning, for the ``with`` block only."""
    drop = _DropRecord(EXTENSION_WARNING)
    torchrl_logger.addFilter(drop)
    try:
        yield
    finally:
        torchrl_logger.removeFilter(drop)


class TorchPrioritizedSampler(PrioritizedSampler):
    """TorchRL's ``PrioritizedSampler`` (Schaul et al. 2016) backed by :class:`FlatPriorityTree`.

    Takes TorchRL's arguments (``max_capacity``, ``alpha``, ``beta``, ``eps``, ...) unchanged.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # TorchRL warns that its C++ trees are missing; this class does not use them.
        with _without_extension_warning():
            super().__init__(*args, **kwargs)

    def _init(self) -> None:
        if self._device is not None and self._device.type != "cpu":
            raise ValueError(
                f"TorchPrioritizedSampler keeps its trees on the CPU, got {self._device}"
            )
        self._sum_tree = FlatPriorityTree(self._max_capacity, "sum", self.dtype)
        self._min_tree = FlatPriorityTree(self._max_capacity, "min", self.dtype)
        self._max_priority = None
