r"""Gentleness from one stated tolerance (beyond the paper): the tolerance rule, the normalised
curiosity and the PID Lagrange multiplier, one function each.

The paper's :math:`\lambda` (eqs. 3-4) and :math:`\lambda'` (eq. 8) are in the newtons of the hand's
fingertips, and it notes that :math:`\lambda'` "may be adjusted dynamically during learning". Here a
user states one number, the tolerance :math:`T`: the impact (eq. 1) one step may deal, in the unit
the rewards read. Everything else follows from it by these rules, written before any run.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import TypeVar

import torch

#: A float or a tensor of them.
T = TypeVar("T", float, torch.Tensor)

#: The paper's :math:`\lambda_2` (N): the impact its acceptability sigmoid (eq. 3) puts at 1/2.
PAPER_LAMBDA_2 = 2.0


def is_finite_number(value: object) -> bool:
    """Whether ``value`` is a real, finite number and not a bool (``True`` is not 1 here)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


def finite(name: str, value: object) -> float:
    """``value`` as a float, or a ``ValueError`` naming ``name`` when it is not a finite number
    (a NaN would stick in every later update; a bool is not a number)."""
    if not is_finite_number(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def check_gains(gains: Sequence[float]) -> tuple[float, float, float]:
    """PID gains ``(K_P, K_I, K_D)`` as floats, each finite and >= 0; else one ``ValueError``."""
    if len(gains) != 3 or not all(is_finite_number(g) and g >= 0 for g in gains):
        raise ValueError(
            f"gains must be [K_P, K_I, K_D], each a finite number >= 0, got {list(gains)}"
        )
    return (float(gains[0]), float(gains[1]), float(gains[2]))


def check_tolerance(tolerance: float) -> float:
    """``tolerance`` as a float, or one ``ValueError``: the one check of a tolerance argument,
    shared by every public function and class that takes one (a run's ``gentleness.tolerance``
    is checked by its config group instead)."""
    if not (is_finite_number(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a finite impact > 0, got {tolerance!r}")
    return float(tolerance)


def tolerance_unit(tolerance: float, lam2: float = PAPER_LAMBDA_2) -> float:
    r"""The force unit :math:`u = T / \lambda_2` in which the penalty reads impacts (tolerance rule).

    Eq. 4 is applied to :math:`\tilde m = m / u`, so an impact at the tolerance costs what the
    paper's :math:`\lambda_2 = 2` N costs on the hand (:math:`r^f = -1`), on every env, and
    :math:`\lambda'` (eq. 8, which reads the penalty) keeps the paper's values. The hand at
    :math:`T = 2` N is the paper unchanged (:math:`u = 1`).

    Example: a finger whose tolerance is 20 N reads impacts in units of 10 N.
    """
    check_tolerance(tolerance)
    if not (is_finite_number(lam2) and lam2 > 0):
        raise ValueError(f"lam2 must be a finite number > 0, got {lam2!r}")
    return tolerance / lam2


def running_mean_update(
    mean: float, count: int, batch_mean: float, min_rate: float = 0.01
) -> tuple[float, int]:
    r"""One step of the curiosity's running scale: :math:`s_k = s_{k-1} + \alpha_k (x_k - s_{k-1})`,
    :math:`\alpha_k = \max(1/k, \alpha_{\min})`.

    The plain mean of the first :math:`1/\alpha_{\min}` batches, then an exponential average that
    follows the model as it learns (as TorchRL's RND normalises its intrinsic reward by running
    statistics). ``x_k``: the batch's mean magnitude of the curiosity (the NLL, or the
    information gain with ``surprise_kind=information_gain``) over its contact steps.
    Returns ``(s_k, k)``.
    """
    if not 0 < min_rate <= 1:
        raise ValueError(f"min_rate must be in (0, 1], got {min_rate}")
    mean, batch_mean = finite("mean", mean), finite("batch_mean", batch_mean)
    if isinstance(count, bool) or not isinstance(count, numbers.Integral) or count < 0:
        raise ValueError(f"count must be an integer >= 0, got {count!r}")
    count = int(count) + 1
    rate = max(1.0 / count, min_rate)
    return mean + rate * (batch_mean - mean), count


def normalized_curiosity(nll: T, scale: float, eps: float = 1e-6) -> T:
    r"""The curiosity of eq. 8 in units of its running scale, :math:`\mathrm{nll} / \max(s, \epsilon)`.

    Off the hand the penalty model's NLL pays 3-60 per contact step (the hand: 1-2, measured);
    divided by its own running mean magnitude on contact steps it pays
    about 1 on every env, so the curiosity cannot outbid the penalty by the env's scale alone.
    Works on floats and tensors alike.
    """
    return nll / max(finite("scale", scale), eps)


def overshoot(impact: float, tolerance: float) -> float:
    r"""The constraint's cost: :math:`\log_2(\max(q, T/2) / T)`, how many doublings the impact
    :math:`q` lies above the tolerance :math:`T` (0 at it, 1 at twice it, -1 at half or below).

    A ratio, so the PID gains need no unit; the floor keeps an episode without contact finite.
    """
    check_tolerance(tolerance)
    if not (is_finite_number(impact) and impact >= 0):
        raise ValueError(f"impact must be a finite number >= 0, got {impact!r}")
    return math.log2(max(impact, tolerance / 2) / tolerance)


def pid_lagrangian(
    cost: float,
    limit: float,
    integral: float,
    previous_cost: float,
    gains: tuple[float, float, float],
    integral_max: float = math.inf,
) -> tuple[float, float]:
    r"""One update of the PID Lagrange multiplier (Stooke, Achiam and Abbeel 2020, Alg. 2).

    .. math::
        e_k = J_k - d, \quad I_k = \min\bigl(I_{\max}, \max(0, I_{k-1} + K_I e_k)\bigr), \quad
        \mu_k = \max\bigl(0,\; K_P e_k + I_k + K_D \max(0, J_k - J_{k-1})\bigr)

    ``cost`` :math:`J_k` and ``limit`` :math:`d` in one unit (here the episodes' max impact's
    :func:`overshoot` of the tolerance, :math:`d = 0`); ``gains`` :math:`(K_P, K_I, K_D)`. The integral only grows
    while the cost is above its limit and is never negative (no wind-up below zero), the
    derivative term acts only on a rising cost; ``integral_max`` :math:`I_{\max}` caps the integral
    (anti-windup: a long overshoot cannot store more than it, so the multiplier falls within
    :math:`I_{\max} / (K_I |e|)` updates once the cost is below its limit). Returns ``(mu_k, I_k)``.
    """
    kp, ki, kd = check_gains(gains)
    if isinstance(integral_max, bool) or not integral_max >= 0:
        raise ValueError(f"integral_max must be >= 0 (inf: no cap), got {integral_max!r}")
    cost, limit = finite("cost", cost), finite("limit", limit)
    integral, previous_cost = finite("integral", integral), finite("previous_cost", previous_cost)
    error = cost - limit
    integral = min(integral_max, max(0.0, integral + ki * error))
    multiplier = max(0.0, kp * error + integral + kd * max(0.0, cost - previous_cost))
    return multiplier, integral


def excess_cost(impact: torch.Tensor, tolerance: float) -> torch.Tensor:
    r"""Method IV's per-step cost: the impact above the tolerance, in tolerances, capped at 1.

    .. math:: c_t = \min\Bigl(1,\; \sum_i \frac{\max(0,\, m^i_t - T)}{T}\Bigr)

    A hinge on the impact of eq. 1 (FORGE's :math:`\mathrm{relu}(F - F_{th})`, Noseworthy et al.
    2024) read in units of the tolerance :math:`T`, so a force unit that is 10x larger, with
    :math:`T` stated in it, gives the same cost. Capped at 1, the per-step cost of Safety Gym's
    indicator costs (Ray et al. 2019): 0 at or below :math:`T`, 1 at :math:`2T` and beyond, so an
    episode's cost :math:`J = \sum_t c_t` counts steps of violation and is bounded by the horizon
    (its critic's support follows from it). ``impact`` ``[..., n_sites]``; returns ``[...]``.
    """
    check_tolerance(tolerance)
    excess = (impact - tolerance).clamp_min(0.0).sum(-1) / tolerance
    return excess.clamp_max(1.0)


def lagrangian_weights(multiplier: float) -> tuple[float, float]:
    r"""The actor's weights on the reward side and on the cost side at Lagrange multiplier
    :math:`\lambda \ge 0`, normalised by :math:`1 + \lambda` (OmniSafe's DDPG-Lag ``_loss_pi``):

    .. math:: \max_\pi \frac{Q_r - \lambda Q_c}{1 + \lambda}
       \;\Rightarrow\; w_r = \frac{1}{1 + \lambda}, \quad w_c = \frac{\lambda}{1 + \lambda}

    (:math:`Q_c` is learned as a penalty :math:`-c`, so both weights are >= 0). The objective's
    scale stays within that of its heads however large :math:`\lambda` grows: a multiplier that
    winds up shifts the trade-off toward the cost, it does not blow up the actor's gradient.
    """
    multiplier = finite("multiplier", multiplier)
    if multiplier < 0:
        raise ValueError(f"multiplier must be >= 0, got {multiplier}")
    return 1.0 / (1.0 + multiplier), multiplier / (1.0 + multiplier)


def normalized_values(q: torch.Tensor, span: torch.Tensor, floor: float = 1e-2) -> torch.Tensor:
    r"""Each head's expected return divided by its batch's mean magnitude (no gradient through it):

    .. math:: \hat Q_k = \frac{Q_k}{\max\bigl(\mathrm{mean}_B |Q_k|,\; \epsilon\,(v^k_{\max} - v^k_{\min})\bigr)}

    the normalisation of TD3+BC (Fujimoto and Gu 2021, :math:`\lambda = \alpha / \mathrm{mean}|Q|`)
    applied per head. Multiplying a component's rewards, and with them its support, by any
    factor leaves :math:`\hat Q_k` unchanged, so no choice of units tips the sum of the heads;
    the floor (:math:`\epsilon` of the head's support ``span``) keeps a head whose values are
    all near 0 (a cost never paid) from being divided by nothing. ``q`` ``[..., B, K]``,
    ``span`` ``[K]`` (or broadcastable); returns ``[..., B, K]``.
    """
    scale = q.detach().abs().mean(-2, keepdim=True)
    return q / torch.maximum(scale, floor * span)
