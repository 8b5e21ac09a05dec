r"""``CostLagrangian``: the task kept, the impacts held under a stated limit (Method IV).

The constrained problem, as safe RL writes it (Altman 1999; Ray et al. 2019):

.. math:: \max_\pi J_r(\pi) \quad \text{s.t.} \quad J_c(\pi) = \mathbb{E}\Bigl[\sum_t c_t\Bigr] \le d,

with :math:`c_t` the impact above the tolerance in tolerances, capped at 1 a step
(:func:`~gentlerl.functional.excess_cost`), and :math:`d` the limit, in the same unit: steps of
violation per episode. The multiplier :math:`\lambda \ge 0` is a PID Lagrangian (Stooke, Achiam
and Abbeel 2020; :func:`~gentlerl.functional.pid_lagrangian`) stepped once per ``period`` env
steps on the mean cost of the last :data:`WINDOW` finished episodes, in limits
(:math:`e = J_c / d - 1`), frozen at 0 for ``warmup_frames`` env steps: OmniSafe's DDPG-PID (one
step per epoch on its logger's 10-episode window, after ``warmup_epochs``: the critics learn
before the trade-off moves), and the actor maximises
:math:`(Q_r - \lambda Q_c) / (1 + \lambda)` (:func:`~gentlerl.functional.lagrangian_weights`),
each head's value divided by its batch magnitude with ``learner.normalize_values``.

No unit enters: :math:`c_t` is in tolerances, :math:`d` in steps, and the normalised heads do
not see their rewards' scale, so a force unit or a task reward 10x larger leaves :math:`\lambda`'s
path and the learned trade-off unchanged (``tests/rewards/test_lagrangian.py`` shows it).

The multiplier weighs the run's constrained head (:func:`constrained_head`): the excess penalty
:math:`-c_t` where the variant learns it (``r+rc``, the constrained baseline), else the paper's
impact penalty :math:`r^f` (``r+rf+rsp`` under the Lagrangian): the constraint is on :math:`J_c`
either way.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from gentlerl import keys
from gentlerl.functional import lagrangian_weights, pid_lagrangian
from gentlerl.functional.constraint import check_gains, is_finite_number
from gentlerl.rewards.multiplier import is_window, window_state

#: Finished episodes whose mean cost is the constraint's :math:`J_c`.
WINDOW = 10


def constrained_head(reward_keys: Sequence[str]) -> str:
    """The head the multiplier weighs: ``excess_penalty`` where the variant has it, else
    ``penalty``; a ``ValueError`` when it has neither."""
    for key in (keys.EXCESS_PENALTY, keys.PENALTY):
        if key in reward_keys:
            return key
    raise ValueError(
        f"a Lagrangian weighs a cost head ({keys.EXCESS_PENALTY} or {keys.PENALTY}); the heads "
        f"{list(reward_keys)} have neither (use a variant with rc or rf)"
    )


def head_weights(reward_keys: Sequence[str], multiplier: float) -> list[float]:
    r"""Each head's weight in the actor's objective at :math:`\lambda` = ``multiplier``:
    :math:`\lambda / (1 + \lambda)` on the constrained head, :math:`1 / (1 + \lambda)` on every
    other (the task and, in the paper's variants, the curiosity)."""
    reward_side, cost_side = lagrangian_weights(multiplier)
    cost = constrained_head(reward_keys)
    return [cost_side if key == cost else reward_side for key in reward_keys]


class CostLagrangian:
    r""":math:`\lambda`, stepped on the finished episodes' costs (:meth:`observe`).

    Args:
        limit: :math:`d > 0`, the episodes' mean cost allowed (steps of violation per episode).
        gains: :math:`(K_P, K_I, K_D)` on the error in limits, :math:`J_c / d - 1`: one set of
            gains serves a limit of 1 on the hand and of 25 on a 1000-step task.
        warmup_frames: env steps before :math:`\lambda` moves (episodes before it still fill the
            window).
        period: env steps between PID steps (half OmniSafe's 2,000-step epoch: a 30k-frame
            run steps 24 times after a warm-up of a fifth of it).
        multiplier_max: the cap of the PID integral (OmniSafe's ``penalty_max``), so a long
            violation cannot store more than it.
        window: :data:`WINDOW` episodes by default.
    """

    def __init__(
        self,
        limit: float,
        gains: tuple[float, float, float],
        warmup_frames: int = 0,
        multiplier_max: float = 100.0,
        window: int = WINDOW,
        period: int = 1000,
    ) -> None:
        if not (is_finite_number(limit) and limit > 0):
            raise ValueError(f"limit must be a finite cost > 0, got {limit!r}")
        if not (_is_count(warmup_frames)):
            raise ValueError(f"warmup_frames must be an integer >= 0, got {warmup_frames!r}")
        if not (is_finite_number(multiplier_max) and multiplier_max >= 0):
            raise ValueError(f"multiplier_max must be a finite number >= 0, got {multiplier_max!r}")
        if not (_is_count(window) and window >= 1):
            raise ValueError(f"window must be an integer >= 1 episode, got {window!r}")
        if not (_is_count(period) and period >= 1):
            raise ValueError(f"period must be an integer >= 1 env step, got {period!r}")
        self.limit, self.gains = float(limit), check_gains(gains)
        self.warmup_frames, self.multiplier_max = int(warmup_frames), float(multiplier_max)
        self.period = int(period)
        #: The env steps at the last :meth:`observe` (-1: none yet).
        self.frames = -1
        self.recent: deque[float] = deque(maxlen=window)
        self.multiplier = self.integral = self.cost = 0.0
        self.episodes = self.steps = 0

    def weights(self, reward_keys: Sequence[str]) -> list[float]:
        """The heads' weights now (:func:`head_weights`)."""
        return head_weights(reward_keys, self.multiplier)

    def observe(self, costs: Iterable[float], frames: int) -> float:
        r"""Take the finished episodes' costs :math:`J = \sum_t c_t` and step the PID once on the
        window's mean where ``frames`` (the run's env steps) has crossed a multiple of ``period``
        since the last call and passed the warm-up. Returns :math:`\lambda`. A non-finite or
        negative cost is refused before anything is taken (it would stick)."""
        costs = list(costs)
        for cost in costs:
            if not (is_finite_number(cost) and cost >= 0):
                raise ValueError(f"an episode's cost must be finite and >= 0, got {cost!r}")
        self.recent.extend(float(c) for c in costs)
        self.episodes += len(costs)
        due = self.frames >= 0 and frames // self.period > self.frames // self.period
        self.frames = frames
        if due and frames > self.warmup_frames and self.recent:
            self._step()
        return self.multiplier

    def _step(self) -> None:
        """One PID update on the window's mean cost in limits: :math:`e = J_c / d - 1`."""
        cost = statistics.fmean(self.recent)
        previous = self.cost if self.steps else cost  # no derivative kick at the first step
        self.multiplier, self.integral = pid_lagrangian(
            cost / self.limit,
            1.0,
            self.integral,
            previous / self.limit,
            self.gains,
            self.multiplier_max,
        )
        self.cost = cost
        self.steps += 1

    def scalars(self) -> dict[str, float]:
        """What a run logs: :math:`\\lambda`, its integral and the window's mean cost."""
        return {
            "lagrange_multiplier": self.multiplier,
            "multiplier_integral": self.integral,
            "episode_cost": self.cost,
        }

    def state_dict(self) -> dict[str, Any]:
        return window_state(self)

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict`'s entries, each checked first (nothing changes on a
        refusal, which names the entry)."""
        expected = {
            "recent": "a list of finite costs >= 0",
            "multiplier": "a finite number >= 0",
            "integral": f"a finite number in [0, {self.multiplier_max}]",
            "cost": "a finite number >= 0",
            "episodes": "an integer >= 0",
            "steps": "an integer >= 0",
            "frames": "an integer >= -1 (-1: none yet)",
        }
        for name, what in expected.items():
            if name not in state or not _valid(name, state[name], self.multiplier_max):
                value = state.get(name, "<missing>")
                raise ValueError(f"CostLagrangian state {name!r}={value!r} must be {what}")
        self.recent.clear()
        self.recent.extend(float(x) for x in state["recent"])
        self.multiplier, self.integral = float(state["multiplier"]), float(state["integral"])
        self.cost = float(state["cost"])
        self.episodes, self.steps = int(state["episodes"]), int(state["steps"])
        self.frames = int(state["frames"])


def _is_count(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _valid(name: str, value: object, integral_max: float) -> bool:
    if name == "recent":
        return is_window(value)
    if name in ("episodes", "steps"):
        return _is_count(value)
    if name == "frames":  # -1: none yet
        return value == -1 or _is_count(value)
    high = integral_max if name == "integral" else math.inf
    return is_finite_number(value) and 0 <= value <= high
