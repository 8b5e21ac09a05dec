"""The paper's gentleness equations (Huang et al. 2019, "Proposed Approach"), one function each.

Shapes follow TorchRL: leading batch dims ``...``, then the feature dims named in each docstring.
All functions are pure, differentiable where it makes sense, and finite for finite inputs of
magnitude up to ~1e15 in float32 (tested; beyond that, squares and sums can overflow float32's
3.4e38). Variances are floored (``gaussian_nll``'s ``min_var``) so a collapsed variance gives a
large but finite NLL.

A non-finite input never becomes a finite reward: NaN and +-inf propagate as NaN or +-inf
(:func:`_floor` keeps them through every ``max``), so a broken sensor or a diverged model shows up
as a non-finite reward that the training loop stops on, not as a plausible number.
"""

from __future__ import annotations

import math

import torch

_LOG_2PI = math.log(2.0 * math.pi)


def _floor(x: torch.Tensor, low: float) -> torch.Tensor:
    """``max(x, low)`` elementwise, except that ``-inf`` becomes NaN (and NaN stays NaN).

    ``clamp_min`` would map ``-inf`` to ``low``, a finite value from a non-finite input.
    ``x * 0`` is 0 for finite ``x`` and NaN for infinite ``x``.
    """
    return torch.where(x < low, x * 0.0 + low, x)


def impact(force: torch.Tensor, next_force: torch.Tensor) -> torch.Tensor:
    r"""Impact per sensor site, :math:`m_t^i = \sum_c \max(0, f^{i,c}_{t+1} - f^{i,c}_t)` (eq. 1).

    The paper sums the per-channel force increase of each fingertip (section "Experimental domain").

    Args:
        force: ``[..., n_sites, n_channels]`` sensed force at step t (N).
        next_force: same shape, sensed force at step t+1 (N).

    Returns:
        ``[..., n_sites]`` non-negative impact (N).
    """
    if force.shape != next_force.shape:
        raise ValueError(
            f"force and next_force must have the same shape [..., n_sites, n_channels], got "
            f"{tuple(force.shape)} and {tuple(next_force.shape)}"
        )
    if force.ndim < 2:
        raise ValueError(
            f"force must have shape [..., n_sites, n_channels], got {tuple(force.shape)}"
        )
    return _floor(next_force - force, 0.0).sum(-1)


def acceptability(x: torch.Tensor, lam1: float, lam2: float) -> torch.Tensor:
    r"""Acceptability of an amount ``x``, :math:`a_\lambda(x) = 1 / (1 + e^{\lambda_1 (x - \lambda_2)})` (eq. 3).

    A sigmoid that is ~1 well below ``lam2`` and ~0 well above it; ``lam1`` sets its steepness.
    Computed as ``sigmoid(lam1 * (lam2 - x))``, which is finite for every finite input.
    """
    if lam1 < 0:
        raise ValueError(f"lam1 (sigmoid steepness) must be >= 0, got {lam1}")
    return torch.sigmoid(lam1 * (lam2 - x))


def impact_penalty(impact: torch.Tensor, lam1: float = 2.0, lam2: float = 2.0) -> torch.Tensor:
    r"""Impact penalty :math:`r^f_t = -\sum_i (1 - a_\lambda(m^i_t))\, m^i_t` (eq. 4), :math:`\lambda = [2, 2]`.

    Examples (``lam = [2, 2]``): a 1 N impact at one fingertip costs ``-(1 - sigmoid(2)) = -0.1192``;
    a 2 N impact costs ``-(1 - sigmoid(0)) * 2 = -1.0``.

    Args:
        impact: ``[..., n_sites]`` impacts :math:`m^i_t` (N), from :func:`impact`. An impact is
            never negative; a negative value counts as no impact, so the penalty is <= 0 for
            every finite input (NaN / inf give NaN / -inf).

    Returns:
        ``[...]`` penalty (<= 0).
    """
    impact = _floor(impact, 0.0)
    return -((1.0 - acceptability(impact, lam1, lam2)) * impact).sum(-1)


def force_penalty(force: torch.Tensor, lam1: float = 2.0, lam2: float = 8.0) -> torch.Tensor:
    r"""Total-force penalty :math:`r^F_t = -\sum_i (1 - a_\lambda(F^i_{t+1}))\, F^i_{t+1}`,
    :math:`F^i = \sum_c f^{i,c}` (beyond the paper: its "future work" on wear).

    Eq. 4 with the force *level* in place of its increase: impacts wear a fingertip at contact,
    a sustained press wears it for as long as it lasts. The acceptability sigmoid (eq. 3) keeps
    the penalty's shape: forces well below :math:`\lambda_2` are almost free, above it each newton
    costs about one unit. The default :math:`\lambda = [2, 8]` lets the hand press as hard as the
    touch task needs (> 5 N normal; one flexing knuckle holds 6.6 N summed over channels when it
    gets there slowly, cost 0.38) and charges hurrying (the same press at the paper regime's
    action scale arrives with 8.1 N: cost 4.4) and every newton past ~8 N (10 N: -9.8).

    Args:
        force: ``[..., n_sites, n_channels]`` non-negative sensed force at step t+1 (N), e.g. the
            hand's ``touch`` (per channel, the sum of |force| over the touch grid).
        lam1, lam2: :math:`\lambda` of the acceptability sigmoid.

    Returns:
        ``[...]`` penalty (<= 0).
    """
    if force.ndim < 2:
        raise ValueError(
            f"force must have shape [..., n_sites, n_channels], got {tuple(force.shape)}"
        )
    return impact_penalty(force.sum(-1), lam1, lam2)


def torque_penalty(torque: torch.Tensor, lam1: float = 4.0, lam2: float = 1.0) -> torch.Tensor:
    r"""Actuator-effort penalty :math:`r^\tau_t = -\sum_j (1 - a_\lambda(|\tau^j_{t+1}|))\, |\tau^j_{t+1}|`
    (beyond the paper: its "future work" on actuator wear).

    Eq. 4 applied to the force each actuator exerts: the sign only says which way a joint is
    driven, the magnitude is what strains the motor and tendon. Efforts well below
    :math:`\lambda_2` are almost free, so holding the hand up against gravity costs little, and
    each unit above it costs about one unit. The default :math:`\lambda = [4, 1]` (N m for the
    Shadow Hand's joint actuators, whose limits are 2.2-4.8 N m) makes the 0.54-0.61 N m that a
    knuckle exerts for the touch task's 5 N press cost 0.07-0.11 and 2 N m cost 1.96.

    Args:
        torque: ``[..., n_actuators]`` actuator forces after the step (the hand's
            ``actuator_force``, MuJoCo ``data.actuator_force``).
        lam1, lam2: :math:`\lambda` of the acceptability sigmoid.

    Returns:
        ``[...]`` penalty (<= 0).
    """
    if torque.ndim < 1:
        raise ValueError(f"torque must have shape [..., n_actuators], got {tuple(torque.shape)}")
    return impact_penalty(torque.abs(), lam1, lam2)


def mixture_moments(
    mean: torch.Tensor, var: torch.Tensor, dim: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Moments of an equally weighted Gaussian mixture (the ensemble's combined prediction).

    .. math::
        \mu_* = \frac{1}{M}\sum_i \mu_i, \qquad
        \sigma^2_* = \frac{1}{M}\sum_i (\sigma_i^2 + \mu_i^2) - \mu_*^2
                   = \frac{1}{M}\sum_i \sigma_i^2 + \frac{1}{M}\sum_i (\mu_i - \mu_*)^2 .

    The second (equal) form is used: it cannot go negative through cancellation.

    Args:
        mean: member means, ensemble members along ``dim``.
        var: member variances, same shape.
        dim: the ensemble dimension.

    Returns:
        ``(mu_star, var_star)`` with ``dim`` reduced.
    """
    if mean.shape != var.shape:
        raise ValueError(
            f"mean and var must have the same shape, got {tuple(mean.shape)} and {tuple(var.shape)}"
        )
    mu_star = mean.mean(dim)
    spread = (mean - mu_star.unsqueeze(dim)).pow(2).mean(dim)
    return mu_star, var.mean(dim) + spread


def gaussian_nll(
    x: torch.Tensor, mean: torch.Tensor, var: torch.Tensor, min_var: float = 1e-6
) -> torch.Tensor:
    r"""Elementwise :math:`-\log \mathcal{N}(x \mid \mu, \sigma^2)`, not summed (used in eqs. 6 and 8).

    .. math:: \tfrac12 \left(\log 2\pi\sigma^2 + (x - \mu)^2 / \sigma^2\right)

    ``var`` is floored at ``min_var`` so that a collapsed variance gives a large but finite value;
    a non-finite ``x``, ``mean`` or ``var`` gives NaN or inf.
    """
    if not min_var > 0:
        raise ValueError(f"min_var must be > 0, got {min_var}")
    var = _floor(var, min_var)
    return 0.5 * (_LOG_2PI + var.log() + (x - mean).pow(2) / var)


def gaussian_nll_parts(
    x: torch.Tensor, mean: torch.Tensor, var: torch.Tensor, min_var: float = 1e-6
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""The two terms of :func:`gaussian_nll`: ``(spread, error)``, elementwise.

    .. math::
        -\log \mathcal{N}(x \mid \mu, \sigma^2)
        = \underbrace{\tfrac12 \log 2\pi\sigma^2}_{\text{spread}}
        + \underbrace{\tfrac12 (x - \mu)^2 / \sigma^2}_{\text{error}}

    A model that is wide but right pays in ``spread``; one that is sure but wrong, in ``error``
    (``2 * error`` is the squared z-score, 1 on average for a calibrated Gaussian). Diagnostics
    only; the rewards use :func:`gaussian_nll`.
    """
    if not min_var > 0:
        raise ValueError(f"min_var must be > 0, got {min_var}")
    var = _floor(var, min_var)
    return 0.5 * (_LOG_2PI + var.log()), 0.5 * (x - mean).pow(2) / var


def information_gain(mean: torch.Tensor, var: torch.Tensor, dim: int = 0) -> torch.Tensor:
    r"""What observing the outcome would teach the ensemble, in nats (beyond the paper).

    .. math::
        I = \tfrac12 \log \frac{\sigma^2_*}{\bar\sigma^2}
          = \tfrac12 \log\Big(1 + \frac{\tfrac1M\sum_i (\mu_i - \mu_*)^2}{\tfrac1M\sum_i \sigma_i^2}\Big),

    the Gaussian approximation of the mutual information between the outcome and the member
    that predicts it: the mixture's variance :math:`\sigma^2_*` (eq. 5) over the members' mean
    variance :math:`\bar\sigma^2`. It is 0 when the members agree (only the aleatoric spread is
    left, which no data removes) and grows with their disagreement (the epistemic part), which
    shrinks as the model sees more of the same contacts: a surprise that fades. Unlike the NLL
    it does not read the outcome, so a model that is miscalibrated but unanimous pays nothing.

    Args:
        mean, var: member means and variances, ensemble members along ``dim``.

    Returns:
        ``[...]`` with ``dim`` reduced, >= 0 (NaN where an input is).
    """
    mu_star, var_star = mixture_moments(mean, var, dim)
    aleatoric = _floor(var.mean(dim), 1e-6)
    return 0.5 * (_floor(var_star, 1e-6) / aleatoric).log()


def penalty_surprise(
    penalty: torch.Tensor, nll: torch.Tensor, lam1: float = 2.0, lam2: float = 2.0
) -> torch.Tensor:
    r"""Penalty-based surprise :math:`r^{s_p}_t` (eq. 8).

    .. math::
        r^{s_p}_t = \begin{cases}
            a_{\lambda'}(r^f_t)\,\left[-\log \mathcal{N}(r^f_t \mid \mu_*, \sigma^2_*) - r^f_t\right]
                & \text{if } r^f_t < 0 \\
            0 & \text{otherwise,}
        \end{cases}

    chosen so that :math:`r^f_t + r^{s_p}_t` is the convex combination of eq. 7:
    :math:`a' \cdot \mathrm{nll} + (1 - a')\, r^f_t`.

    Reading of :math:`a_{\lambda'}(r^f_t)`: the paper applies the impact acceptability sigmoid to the
    penalty, and wants high penalties to be *less* acceptable (mostly penalty, little curiosity). Since
    :math:`r^f_t \le 0`, we evaluate the acceptability of the penalty's *magnitude*:
    ``a' = acceptability(-penalty, lam1, lam2)`` (~1 for small penalties, ~0 for large ones).

    Args:
        penalty: ``[...]`` impact penalty :math:`r^f_t` (<= 0).
        nll: ``[...]`` :math:`-\log \mathcal{N}(r^f_t \mid \mu_*, \sigma^2_*)` under the target
            penalty model, from :func:`gaussian_nll` and :func:`mixture_moments`.
        lam1, lam2: :math:`\lambda'` (paper: :math:`\lambda'_1 = 2`, :math:`\lambda'_2 \in [1, 4]`).

    Returns:
        ``[...]`` penalty surprise; exactly 0 where ``penalty >= 0`` and both inputs are finite;
        NaN or inf where either is not (eq. 8's "otherwise" branch must not hide a NaN penalty).
    """
    weight = acceptability(-penalty, lam1, lam2)
    surprise = weight * (nll - penalty)
    no_penalty = (penalty >= 0) & torch.isfinite(penalty) & torch.isfinite(nll)
    return torch.where(no_penalty, torch.zeros_like(surprise), surprise)
