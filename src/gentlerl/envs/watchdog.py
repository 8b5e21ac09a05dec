"""``ForceWatchdog``: stop an episode before the hand or the block sees more force than it tolerates."""

from __future__ import annotations

import math

import numpy as np

#: N: a mapped force (the sensor map's) below minus this is a sensor fault, not a force.
NEGATIVE_TOLERANCE = 1.0


def _plausible(force: np.ndarray) -> bool:
    return bool(np.isfinite(force).all() and (force >= -NEGATIVE_TOLERANCE).all())


def _limit(name: str, value: float | None) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not (
        isinstance(value, int | float | np.floating | np.integer)
        and math.isfinite(value)
        and value > 0
    ):
        raise ValueError(f"{name} must be a positive finite force in N (or None), got {value!r}")
    return float(value)


class ForceWatchdog:
    """Trips when a fingertip force or the block force exceeds its limit.

    :class:`~gentlerl.envs.DriverHandEnv` checks it after every control step: on a trip it
    re-commands the last targets under which every force was within limits (the targets before
    the step), ends the episode (``terminated``) and writes ``watchdog=True``; the next reset
    starts afresh. Exploration therefore never holds a pose past the limit for more than one
    control step (50 ms). Set the limits below what the hardware tolerates and above the task's
    success force (5 N for touch), or success becomes impossible.

    Args:
        fingertip_limit: N, compared with each fingertip's mapped force summed over its
            channels (the ``touch`` row); ``None``: not watched.
        block_limit: N, compared with the block sensor's force; ``None``: not watched.

    Attributes:
        trips: trips so far; ``fingertip_trips`` / ``block_trips`` / ``fault_trips`` (a reading
            that cannot be trusted) by cause (a step over both limits counts in both),
            ``checks``: steps checked.
    """

    def __init__(
        self, fingertip_limit: float | None = 15.0, block_limit: float | None = None
    ) -> None:
        self.fingertip_limit = _limit("fingertip_limit", fingertip_limit)
        self.block_limit = _limit("block_limit", block_limit)
        if self.fingertip_limit is None and self.block_limit is None:
            raise ValueError("ForceWatchdog needs fingertip_limit and/or block_limit, got neither")
        self.trips = self.fingertip_trips = self.block_trips = self.fault_trips = 0
        self.checks = 0

    def check(self, touch: np.ndarray, block_force: float | None) -> bool:
        """Whether this step's forces trip the watchdog (and count it). Fails closed: a reading
        that is not finite, of the wrong shape or implausibly negative (below
        ``-NEGATIVE_TOLERANCE`` N) trips it too (``fault_trips``), as does a missing block force
        when ``block_limit`` is set.

        ``touch``: ``[5, C]`` fingertip forces from the sensor map (N); ``block_force``: N or ``None``.
        """
        self.checks += 1
        touch = np.asarray(touch, dtype=np.float64)
        tip = block = fault = False
        if self.fingertip_limit is not None:
            if touch.ndim != 2 or touch.size == 0 or not _plausible(touch):
                fault = True
            else:
                tip = bool((touch.sum(-1) > self.fingertip_limit).any())
        if self.block_limit is not None:
            if block_force is None or not _plausible(np.asarray(block_force, dtype=np.float64)):
                fault = True
            else:
                block = float(block_force) > self.block_limit
        self.fingertip_trips += tip
        self.block_trips += block
        self.fault_trips += fault
        self.trips += tip or block or fault
        return tip or block or fault

    def counts(self) -> dict[str, int]:
        """``trips``, ``fingertip_trips``, ``block_trips``, ``checks`` (for logs and reports)."""
        return {
            "trips": self.trips,
            "fingertip_trips": self.fingertip_trips,
            "block_trips": self.block_trips,
            "fault_trips": self.fault_trips,
            "checks": self.checks,
        }

    def __repr__(self) -> str:
        return (
            f"ForceWatchdog(fingertip_limit={self.fingertip_limit}, "
            f"block_limit={self.block_limit}, trips={self.trips})"
        )
