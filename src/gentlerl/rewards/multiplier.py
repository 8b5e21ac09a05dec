r"""``ImpactMultiplier``: the impact penalty's weight, steered toward a stated tolerance.

The paper fixes the trade-off between the task and the impact penalty by hand (:math:`\lambda'`,
which it says "may be adjusted dynamically during learning"). Here the penalty's weight in the
agent's objective is :math:`w = w_0 + \mu` (:math:`w_0 = 1` keeps at least the paper's weight,
:math:`w_0 = 0` is a plain Lagrangian), where :math:`\mu \ge 0` is a PID Lagrange multiplier
(Stooke et al. 2020; :func:`~gentlerl.functional.pid_lagrangian`) on the constraint "the episodes'
max impact stays at the tolerance": after each finished episode,

.. math:: J_k = \log_2 \frac{\max(q_k, T/2)}{T}, \quad
   q_k = \mathrm{median}(\text{max impact of the last } W \text{ episodes}), \qquad d = 0:

the error is the factor by which the episodes overshoot the tolerance, in doublings (a ratio
has no unit, so one set of gains serves every env), and an episode at half the tolerance or
below counts as -1 (no contact at all would otherwise be :math:`-\infty`). With a ``period``
the update runs once per ``period`` env steps instead (on the same median), so that short
episodes do not step the controller faster than long ones, and ``integral_max`` caps its
integral. The loop may also feed it the max impacts of a few
noise-free episodes of the current actor at each step (``gentleness.multiplier_episodes``: the
deployed policy's cost, not the exploring one's).

A multi-critic agent (gentlerl's D4PG) puts :math:`w` on the penalty head in its actor's
objective (``MultiHeadD4PGLoss.set_head_weight``); the critics keep learning the unweighted
components, so changing :math:`w` needs no relabelled buffer. A single-critic agent puts it on the
penalty's weight in ``SumRewards`` (rescored at sampling), and any loop steps it from its
collector's batches (:meth:`ImpactMultiplier.observe_batch`).
"""

from __future__ import annotations

import math
import numbers
import statistics
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import torch
from tensordict import TensorDictBase

from gentlerl import keys
from gentlerl.functional import overshoot, pid_lagrangian
from gentlerl.functional.constraint import check_gains, check_tolerance, is_finite_number

#: Finished episodes whose median max impact is the constraint's cost.
WINDOW = 10


class ImpactMultiplier:
    r"""The penalty's weight ``base + mu``; :meth:`observe` the finished episodes' max impacts.

    Args:
        tolerance: :math:`T`, the impact one step may deal (the unit of the observed impacts).
        gains: :math:`(K_P, K_I, K_D)` on the error in doublings above the tolerance.
        window: :data:`WINDOW` episodes by default.
        period: ``None``: one PID step per finished episode.
            ``N``: one PID step per ``N`` env steps, on the window's median (episodes of every
            length then steer at one rate per frame).
        integral_max: the cap of the PID integral (anti-windup; ``None``: no cap).
        base: :math:`w_0`, the weight at :math:`\mu = 0` (1: the paper's weight is the floor;
            0: a plain Lagrangian, no penalty while the cost is below its limit).
    """

    def __init__(
        self,
        tolerance: float,
        gains: tuple[float, float, float],
        window: int = WINDOW,
        period: int | None = None,
        integral_max: float | None = None,
        base: float = 1.0,
    ) -> None:
        tolerance, gains = check_tolerance(tolerance), check_gains(gains)
        if not (_is_integer(window) and window >= 1):
            raise ValueError(f"window must be an integer >= 1 episode, got {window!r}")
        if period is not None and not (_is_integer(period) and period >= 1):
            raise ValueError(f"period must be an integer >= 1 env step (or None), got {period!r}")
        if not (is_finite_number(base) and base >= 0):
            raise ValueError(f"base must be a finite weight >= 0, got {base!r}")
        integral_max = math.inf if integral_max is None else integral_max
        if isinstance(integral_max, bool) or not integral_max >= 0:
            raise ValueError(f"integral_max must be a number >= 0 (or None), got {integral_max!r}")
        self.tolerance, self.gains = tolerance, gains
        self.period, self.integral_max, self.base = period, float(integral_max), float(base)
        self.recent: deque[float] = deque(maxlen=window)
        self.multiplier = self.integral = self.cost = 0.0
        self.episodes = self.steps = 0
        #: The env steps at the last :meth:`observe` with ``period`` (-1: none yet).
        self.frames = -1
        #: :meth:`observe_batch`'s episodes still running: trajectory id -> max impact so far.
        self._open: dict[int, float] = {}

    @property
    def weight(self) -> float:
        r""":math:`w = w_0 + \mu`: the penalty's weight in the objective."""
        return self.base + self.multiplier

    def observe(self, max_impacts: Iterable[float], frames: int | None = None) -> float:
        """Take the finished episodes' max impacts (in the tolerance's unit) and step the PID:
        per episode, or with ``period`` once per multiple of it that ``frames`` (the run's env
        steps so far) has passed since the last call. Returns the new :attr:`weight`. A
        non-finite impact is refused (it would stick)."""
        for impact in max_impacts:
            if not math.isfinite(impact) or impact < 0:
                raise ValueError(f"an episode's max impact must be finite and >= 0, got {impact}")
            self.recent.append(float(impact))
            self.episodes += 1
            if self.period is None:
                self._step()
        if self.period is not None:
            if frames is None:
                raise ValueError(f"period={self.period} steps on env steps: pass frames")
            crossed = 0 if self.frames < 0 else frames // self.period - self.frames // self.period
            self.frames = frames
            for _ in range(crossed if self.recent else 0):
                self._step()
        return self.weight

    def due(self, frames: int) -> bool:
        """Whether :meth:`observe` at ``frames`` env steps would step the PID (``period`` set,
        a multiple of it passed since the last call): when to measure the cost, if measuring
        costs something (e.g. noise-free episodes)."""
        if self.period is None:
            raise ValueError("due() needs a period: without one the PID steps per episode")
        return self.frames >= 0 and frames // self.period > self.frames // self.period

    def observe_batch(self, batch: TensorDictBase, frames: int | None = None) -> float:
        """:meth:`observe` a batch of a TorchRL collector (any loop's, e.g. SAC's): the max
        impact (``("next", "impact")``, over sites and steps) of each episode that ends in it,
        an episode told by the collector's ``("collector", "traj_ids")``; an episode that
        continues into the next batch carries its max there (not checkpointed). A non-finite
        impact is refused before anything is taken (a NaN step would otherwise read as 0 N and
        hide the episode's peak)."""
        flat = batch.reshape(-1)
        traj = flat.get(("collector", "traj_ids")).reshape(-1)
        impact = flat.get(("next", keys.IMPACT)).reshape(len(flat), -1)
        bad = ~torch.isfinite(impact).all(-1)
        if bad.any():
            raise ValueError(
                f'("next", {keys.IMPACT!r}) holds a non-finite impact at {int(bad.sum())} of '
                f"{len(flat)} steps (first: {impact[bad][0].tolist()}): the episodes' max impact "
                "needs finite impacts"
            )
        impact = impact.amax(-1)
        done = flat.get(("next", keys.DONE)).reshape(-1)
        finished = []
        for tid in torch.unique(traj).tolist():
            mask = traj == tid
            peak = max(self._open.pop(tid, 0.0), impact[mask].max().item())
            if done[mask].any():
                finished.append(peak)
            else:
                self._open[tid] = peak
        return self.observe(finished, frames)

    def _step(self) -> None:
        """One PID update on the window's median max impact."""
        cost = overshoot(statistics.median(self.recent), self.tolerance)
        previous = self.cost if self.steps else cost  # no derivative kick at the first
        self.multiplier, self.integral = pid_lagrangian(
            cost, 0.0, self.integral, previous, self.gains, self.integral_max
        )
        self.cost = cost
        self.steps += 1

    def scalars(self) -> dict[str, float]:
        """What a run logs: the weight, the multiplier's integral and the cost (doublings)."""
        return {
            "penalty_weight": self.weight,
            "multiplier_integral": self.integral,
            "impact_cost": self.cost,
        }

    def state_dict(self) -> dict[str, Any]:
        return window_state(self)

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict`'s entries, each checked first (a tampered or corrupt one
        is refused in one line naming it, and nothing is changed)."""
        for name in ("recent", "multiplier", "integral", "cost", "episodes"):
            if name not in state:
                raise ValueError(f"ImpactMultiplier state lacks {name!r}")
        # saved before the period existed: one step per episode, no frames seen
        state = {"steps": state["episodes"], "frames": -1, **state}
        recent = state["recent"]
        if not is_window(recent):
            _refuse("recent", recent, "a list of finite impacts >= 0")
        checks = {
            "multiplier": (is_finite_number, 0.0, math.inf, "a finite number >= 0"),
            "integral": (
                is_finite_number, 0.0, self.integral_max,
                f"a finite number in [0, {self.integral_max}] (integral_max)",
            ),
            "cost": (is_finite_number, -math.inf, math.inf, "a finite number"),
            "episodes": (_is_integer, 0, math.inf, "an integer >= 0"),
            "steps": (_is_integer, 0, math.inf, "an integer >= 0"),
            "frames": (_is_integer, -1, math.inf, "an integer >= -1 (-1: none yet)"),
        }  # fmt: skip
        for name, (kind, low, high, expected) in checks.items():
            if not (kind(state[name]) and low <= state[name] <= high):
                _refuse(name, state[name], expected)
        self.recent.clear()
        self.recent.extend(float(x) for x in recent)
        self.multiplier, self.integral = float(state["multiplier"]), float(state["integral"])
        self.cost, self.episodes = float(state["cost"]), int(state["episodes"])
        self.steps, self.frames = int(state["steps"]), int(state["frames"])


#: What a windowed PID controller saves (:class:`ImpactMultiplier`,
#: :class:`~gentlerl.rewards.lagrangian.CostLagrangian`): its window, multiplier and integral,
#: last cost and its counters.
WINDOW_STATE = ("recent", "multiplier", "integral", "cost", "episodes", "steps", "frames")


def window_state(controller: Any) -> dict[str, Any]:
    """The :data:`WINDOW_STATE` entries of ``controller`` (its window as a list)."""
    state = {name: getattr(controller, name) for name in WINDOW_STATE}
    return {**state, "recent": list(state["recent"])}


def is_window(recent: object) -> bool:
    """Whether a saved window ``recent`` is a list of finite numbers >= 0."""
    return (
        isinstance(recent, Sequence)
        and not isinstance(recent, str)
        and all(is_finite_number(x) and x >= 0 for x in recent)
    )


def _is_integer(value: object) -> bool:
    """Whether ``value`` is an integer and not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _refuse(name: str, value: object, expected: str) -> None:
    raise ValueError(f"ImpactMultiplier state {name!r}={value!r} must be {expected}")
