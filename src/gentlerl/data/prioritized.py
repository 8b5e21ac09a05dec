"""TorchRL's ``PrioritizedSampler`` with its priority trees in plain torch.

The TorchRL 0.14.1 wheel's C++ segment trees (``torchrl._torchrl``) do not load against the pinned
torch 2.13.0 CPU wheel (undefined symbol), and TorchRL then refuses to build a
``PrioritizedSampler``. :class:`TorchPrioritizedSampler` keeps *all* of TorchRL's sampler logic
(alpha/beta, importance weights, ``update_priority``, state dicts, schedulers) and swaps only the two
trees for :class:`FlatPriorityTree`: a flat tensor whose range sums/minima are vectorised
reductions and whose prefix-sum search is ``cumsum`` + ``searchsorted`` over the entries written
so far. Each sample costs O(entries written) in C-speed torch ops (about 1 ms for 1M), no python
loop: a paper-scale buffer (1M slots) holding its first 25k transitions scans 25k.

On a CUDA storage the trees live on the GPU and TorchRL's own CUDA path samples (its compiled
CUDA trees do not load either): the trees then make no host read (range queries are masked
reductions that stay tensors, the search scans every slot); what still waits for the GPU is
TorchRL's masking of invalid indices in a priority update.

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
    """The subset of TorchRL's ``Sum/MinSegmentTree`` interface the sampler uses, on a flat tensor.

    Args:
        capacity, reduce, dtype: the slots, ``"sum"`` or ``"min"``, the priorities' dtype.
        device: where the entries live (``.device``, which TorchRL's sampler reads).
        host_reads: track the highest entry written (an ``int`` read of each write's indices)
            so that the prefix-sum search stops there, and answer :meth:`query` with a float;
            default: on the CPU only. Without (a GPU's trees), every search scans all slots and
            a query with tensor bounds returns a tensor, so nothing waits for the device.
    """

    def __init__(
        self,
        capacity: int,
        reduce: Literal["sum", "min"],
        dtype: torch.dtype,
        device: torch.device | str = "cpu",
        *,
        host_reads: bool | None = None,
    ) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        if reduce not in ("sum", "min"):
            raise ValueError(f"reduce must be 'sum' or 'min', got {reduce!r}")
        self.reduce = reduce
        self.neutral = 0.0 if reduce == "sum" else float("inf")
        self.device = torch.device(device)
        self.host_reads = self.device.type == "cpu" if host_reads is None else host_reads
        self.values = torch.full((capacity,), self.neutral, dtype=dtype, device=self.device)

    @property
    def values(self) -> torch.Tensor:
        """The ``[capacity]`` entries (the neutral value where none was written)."""
        return self._values

    @values.setter
    def values(self, values: torch.Tensor) -> None:
        self._values = values
        if not self.host_reads:  # every slot, whatever was written
            self.extent = len(values)
            return
        written = (values != self.neutral).nonzero()
        #: One past the highest entry written: the prefix-sum search reads no further.
        self.extent = int(written[-1]) + 1 if len(written) else 0

    def _index(self, index: int | np.ndarray | torch.Tensor) -> torch.Tensor:
        return torch.as_tensor(index, dtype=torch.long, device=self.device)

    def __getitem__(self, index: int | np.ndarray | torch.Tensor) -> torch.Tensor:
        return self.values[self._index(index)]

    def __setitem__(
        self, index: int | np.ndarray | torch.Tensor, value: float | np.ndarray | torch.Tensor
    ) -> None:
        index = self._index(index)
        self.values[index] = torch.as_tensor(value, dtype=self.values.dtype, device=self.device)
        if self.host_reads and index.numel():
            self.extent = max(self.extent, int(index.max()) + 1)

    def to(self, device: torch.device | str) -> FlatPriorityTree:
        """This tree's entries on ``device`` (host reads as that device's default)."""
        tree = FlatPriorityTree(1, self.reduce, self.values.dtype, device)
        tree.values = self.values.to(tree.device)
        return tree

    def query(self, left: int | torch.Tensor, right: int | torch.Tensor) -> float | torch.Tensor:
        """Sum (or min) of the entries in ``[left, right)``: a float, or without
        :attr:`host_reads` and with tensor bounds a 0-d tensor on the tree's device."""
        if self.host_reads or not isinstance(left, torch.Tensor):
            window = self.values[int(left) : int(right)]
            return float(window.sum() if self.reduce == "sum" else window.min())
        slot = torch.arange(len(self.values), device=self.device)
        inside = (slot >= left) & (slot < right)
        window = torch.where(inside, self.values, self.neutral)
        return window.sum() if self.reduce == "sum" else window.amin()

    def scan_lower_bound(self, mass: np.ndarray | torch.Tensor) -> torch.Tensor:
        """Smallest index whose inclusive prefix sum exceeds each ``mass`` (``extent`` where none
        does among the entries written; the sampler clamps it into the storage)."""
        cumulative = self.values[: self.extent].cumsum(0)
        mass = torch.as_tensor(mass, dtype=cumulative.dtype, device=self.device)
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
        # TorchRL moves the trees to a CUDA storage's device (``_maybe_init_from_storage``).
        device = self._trees_device
        self._sum_tree = FlatPriorityTree(self._max_capacity, "sum", self.dtype, device)
        self._min_tree = FlatPriorityTree(self._max_capacity, "min", self.dtype, device)
        self._max_priority = None

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """TorchRL's, then the trees moved to this sampler's device: a checkpoint is read onto
        the CPU, and a GPU buffer would otherwise rebuild empty trees at its first sample."""
        super().load_state_dict(state_dict)
        for name in ("_sum_tree", "_min_tree"):
            if getattr(self, name).device != self._trees_device:
                setattr(self, name, getattr(self, name).to(self._trees_device))

    @property
    def _trees_device(self) -> torch.device:
        """Where the trees belong: the sampler's device (a CUDA storage's), else the CPU."""
        return self._device if self._device is not None else torch.device("cpu")
