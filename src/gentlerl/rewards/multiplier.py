r"""``ImpactMultiplier``: the impact penalty's weight, steered toward a stated tolerance.

The paper fixes the trade-off between the task and the impact penalty by hand (:math:`\lambda'`,
which it says "may be adjusted dynamically during learning"). Here the penalty's weight in the
agent's objective is :math:`w = 1 + \mu`, where :math:`\mu \ge 0` is a PID Lagrange multiplier
(Stooke et al. 2020; :func:`~gentlerl.functional.pid_lagrangian`) on the constraint "the episodes'
max impact stays at the tolerance": after each finished episode,

.. math:: J_k = \log_2 \frac{\max(q_k, T/2)}{T}, \quad
   q_k = \mathrm{median}(\text{max impact of the last } W \text{ episodes}), \qquad d = 0:

the error is the factor by which the episodes overshoot the tolerance, in doublings (a ratio
has no unit, so one set of gains serves every env), and an episode at half the tolerance or
below counts as -1 (no contact at all would otherwise be :math:`-\infty`).

A multi-critic agent (gentlerl's D4PG) puts :math:`w` on the penalty head in its actor's
objective (``MultiHeadD4PGLoss.set_head_weight``); the critics keep learning the unweighted
components, so changing :math:`w` needs no relabelled buffer. A single-critic agent puts it on the
penalty's weight in ``SumRewards`` (rescored at sampling).
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from collections.abc import Iterable, Mapping
from typing import Any

from gentlerl.functional import overshoot, pid_lagrangian

#: Finished episodes whose median max impact is the constraint's cost.
WINDOW = 10


class ImpactMultiplier:
    """The penalty's weight ``1 + mu``; :meth:`observe` each finished episode's max impact.

    Args:
        tolerance: :math:`T`, the impact one step may deal (the unit of the observed impacts).
        gains: :math:`(K_P, K_I, K_D)` on the error in doublings above the tolerance.
        window: :data:`WINDOW` episodes by default.
    """

    def __init__(
        self, tolerance: float, gains: tuple[float, float, float], window: int = WINDOW
    ) -> None:
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"tolerance must be a finite impact > 0, got {tolerance!r}")
        if len(gains) != 3 or min(gains) < 0:
            raise ValueError(f"gains must be [K_P, K_I, K_D] >= 0, got {gains}")
        if window < 1:
            raise ValueError(f"window must be >= 1 episode, got {window}")
        self.tolerance, self.gains = float(tolerance), tuple(float(g) for g in gains)
        self.recent: deque[float] = deque(maxlen=window)
        self.multiplier = self.integral = self.cost = 0.0
        self.episodes = 0

    @property
    def weight(self) -> float:
        """:math:`w = 1 + \\mu`: the penalty's weight in the objective."""
        return 1.0 + self.multiplier

    def observe(self, max_impacts: Iterable[float]) -> float:
        """One PID update per finished episode (its max impact, in the tolerance's unit);
        returns the new :attr:`weight`. A non-finite impact is refused (it would stick)."""
        for impact in max_impacts:
            if not math.isfinite(impact) or impact < 0:
                raise ValueError(f"an episode's max impact must be finite and >= 0, got {impact}")
            self.recent.append(float(impact))
            cost = overshoot(statistics.median(self.recent), self.tolerance)
            previous = self.cost if self.episodes else cost  # no derivative kick at the first
            self.multiplier, self.integral = pid_lagrangian(
                cost, 0.0, self.integral, previous, self.gains
            )
            self.cost = cost
            self.episodes += 1
        return self.weight

    def scalars(self) -> dict[str, float]:
        """What a run logs: the weight, the multiplier's integral and the cost (doublings)."""
        return {
            "penalty_weight": self.weight,
            "multiplier_integral": self.integral,
            "impact_cost": self.cost,
        }

    def state_dict(self) -> dict[str, Any]:
        return {
            "recent": list(self.recent),
            "multiplier": self.multiplier,
            "integral": self.integral,
            "cost": self.cost,
            "episodes": self.episodes,
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        self.recent.clear()
        self.recent.extend(float(x) for x in state["recent"])
        self.multiplier, self.integral = float(state["multiplier"]), float(state["integral"])
        self.cost, self.episodes = float(state["cost"]), int(state["episodes"])
