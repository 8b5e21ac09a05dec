"""Every function of gentlerl.functional at asymmetric, non-default settings, against numbers
worked out here by hand (the formulas written out with ``math``, never the module's own helpers).

The paper's defaults hide argument-order bugs: at ``lam = (2, 2)`` swapping lambda_1 and lambda_2
changes nothing. Here every lambda pair is unequal, every batch has several sites and channels,
and each expected value is the equation of the paper (eqs. 1, 3-8) or of the method's own
docstring, evaluated in the test.
"""

import math

import pytest
import torch

from gentlerl.functional import (
    acceptability,
    categorical_projection,
    categorical_support,
    force_penalty,
    gaussian_nll,
    gaussian_nll_parts,
    impact,
    impact_penalty,
    information_gain,
    mixture_moments,
    normalized_curiosity,
    overshoot,
    penalty_surprise,
    pid_lagrangian,
    running_mean_update,
    tolerance_unit,
    torque_penalty,
)


def _t(values) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float64)


def _a(x: float, lam1: float, lam2: float) -> float:
    """Eq. 3 as the paper writes it: 1 / (1 + exp(lambda_1 (x - lambda_2)))."""
    return 1.0 / (1.0 + math.exp(lam1 * (x - lam2)))


def _cost(m: float, lam1: float, lam2: float) -> float:
    """One site's term of eq. 4: (1 - a(m)) m."""
    return (1.0 - _a(m, lam1, lam2)) * m


def test_impact_sums_each_sites_rising_channels_over_several_sites_and_channels():
    # eq. 1, 2 transitions x 3 sites x 2 channels; falling channels count 0.
    force = _t([[[1.0, 2.0], [0.5, 0.0], [3.0, 3.0]], [[0.0, 0.0], [2.0, 1.0], [1.0, 4.0]]])
    nxt = _t([[[1.5, 1.0], [2.0, 0.25], [3.0, 7.0]], [[0.75, 0.5], [1.0, 1.0], [0.0, 4.5]]])
    expected = [
        [0.5 + 0.0, 1.5 + 0.25, 0.0 + 4.0],
        [0.75 + 0.5, 0.0 + 0.0, 0.0 + 0.5],
    ]
    torch.testing.assert_close(impact(force, nxt), _t(expected))


def test_acceptability_at_lambda_1_4_is_the_papers_sigmoid_not_its_mirror():
    # lam = (1, 4): 1 / (1 + e^{1 (x - 4)}); x = 3 -> 1 / (1 + e^-1) = 0.7311, x = 5 -> 0.2689,
    # x = 4 -> 0.5. With the lambdas swapped (4, 1) x = 3 would give 1 / (1 + e^8) = 0.0003.
    got = acceptability(_t([3.0, 5.0, 4.0, 0.0]), 1.0, 4.0)
    expected = [1 / (1 + math.exp(-1)), 1 / (1 + math.exp(1)), 0.5, 1 / (1 + math.exp(-4))]
    torch.testing.assert_close(got, _t(expected))
    assert got[0].item() == pytest.approx(0.7311, abs=1e-4)
    assert got[1].item() == pytest.approx(0.2689, abs=1e-4)


def test_impact_penalty_at_lambda_1_4_over_several_sites():
    # A 3 N impact costs -(1 - sigmoid(1 * (4 - 3))) * 3 = -0.807 (reversed lambdas: -3.00).
    one = impact_penalty(_t([3.0]), 1.0, 4.0)
    assert one.item() == pytest.approx(-0.8068, abs=1e-4)
    assert one.item() == pytest.approx(-_cost(3.0, 1.0, 4.0), rel=1e-12)
    # Sites [3, 6, 0.5] at one step, [0, 0, 10] at the next: eq. 4 sums over sites.
    m = _t([[3.0, 6.0, 0.5], [0.0, 0.0, 10.0]])
    expected = [
        -(_cost(3.0, 1, 4) + _cost(6.0, 1, 4) + _cost(0.5, 1, 4)),
        -_cost(10.0, 1, 4),
    ]
    torch.testing.assert_close(impact_penalty(m, 1.0, 4.0), _t(expected))
    # 6 N: -(e^2 / (1 + e^2)) 6 = -5.2848; 0.5 N: -(e^-3.5 / (1 + e^-3.5)) 0.5 = -0.0146.
    assert impact_penalty(_t([6.0]), 1.0, 4.0).item() == pytest.approx(-5.2848, abs=1e-4)
    assert impact_penalty(_t([0.5]), 1.0, 4.0).item() == pytest.approx(-0.0146, abs=1e-4)
    # The mirror setting (4, 1) is a different, much harsher penalty: 3 N costs -2.999.
    assert impact_penalty(_t([3.0]), 4.0, 1.0).item() == pytest.approx(-2.9990, abs=1e-4)


def test_force_penalty_charges_each_sites_channel_sum_at_lambda_half_6():
    # Sites' totals F = [3 + 2, 1 + 0.5, 0 + 0] = [5, 1.5, 0] under lam = (0.5, 6).
    force = _t([[3.0, 2.0], [1.0, 0.5], [0.0, 0.0]])
    expected = -(_cost(5.0, 0.5, 6.0) + _cost(1.5, 0.5, 6.0))
    assert force_penalty(force, 0.5, 6.0).item() == pytest.approx(expected, rel=1e-12)
    # 5 N: (1 - 1 / (1 + e^-0.5)) 5 = 1.8877; 1.5 N: (1 - 1 / (1 + e^-2.25)) 1.5 = 0.1430.
    assert expected == pytest.approx(-(1.8877 + 0.1430), abs=2e-4)


def test_torque_penalty_charges_effort_magnitudes_at_lambda_3_half():
    # |tau| = [1, 0.2, 0.8] under lam = (3, 0.5): the sign of a torque does not matter.
    torque = _t([[-1.0, 0.2, 0.8], [1.0, -0.2, -0.8]])
    one = -(_cost(1.0, 3.0, 0.5) + _cost(0.2, 3.0, 0.5) + _cost(0.8, 3.0, 0.5))
    torch.testing.assert_close(torque_penalty(torque, 3.0, 0.5), _t([one, one]))
    # 1 N m: (1 - 1 / (1 + e^1.5)) = 0.8176.
    assert torque_penalty(_t([1.0]), 3.0, 0.5).item() == pytest.approx(-0.8176, abs=1e-4)


def test_mixture_moments_of_three_unequal_members():
    # means [0, 2, 4], variances [1, 2, 6]: mu* = 2, sigma*^2 = mean var 3 + spread (4 + 0 + 4)/3.
    mean = _t([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0]])
    var = _t([[1.0, 0.5], [2.0, 0.5], [6.0, 0.5]])
    mu, sigma2 = mixture_moments(mean, var, dim=0)
    torch.testing.assert_close(mu, _t([2.0, 1.0]))
    torch.testing.assert_close(sigma2, _t([3.0 + 8.0 / 3.0, 0.5]))
    # the members along dim=1 instead
    mu1, sigma21 = mixture_moments(mean.T, var.T, dim=1)
    torch.testing.assert_close(mu1, mu)
    torch.testing.assert_close(sigma21, sigma2)


def test_gaussian_nll_and_its_parts_with_an_asymmetric_error_and_a_custom_floor():
    # x = 1, mu = 0.25, sigma^2 = 0.5: 1/2 (log(2 pi 0.5) + 0.75^2 / 0.5).
    spread = 0.5 * math.log(2 * math.pi * 0.5)
    error = 0.5 * 0.75**2 / 0.5
    assert gaussian_nll(_t([1.0]), _t([0.25]), _t([0.5])).item() == pytest.approx(
        spread + error, rel=1e-12
    )
    parts = gaussian_nll_parts(_t([1.0]), _t([0.25]), _t([0.5]))
    assert parts[0].item() == pytest.approx(spread, rel=1e-12)
    assert parts[1].item() == pytest.approx(error, rel=1e-12)
    # min_var = 2 floors 0.5 up to 2: 1/2 (log(4 pi) + 0.5625 / 2).
    floored = 0.5 * (math.log(4 * math.pi) + 0.5625 / 2)
    assert gaussian_nll(_t([1.0]), _t([0.25]), _t([0.5]), min_var=2.0).item() == pytest.approx(
        floored, rel=1e-12
    )
    parts = gaussian_nll_parts(_t([1.0]), _t([0.25]), _t([0.5]), min_var=2.0)
    assert parts[1].item() == pytest.approx(0.5625 / 4, rel=1e-12)


def test_information_gain_is_half_the_log_of_mixture_over_mean_variance():
    # means [0, 2], variances [1, 3]: sigma*^2 = 2 + 1 = 3, mean variance 2 -> 1/2 log(3/2);
    # members that agree (second entry) gain nothing.
    mean = _t([[0.0, 5.0], [2.0, 5.0]])
    var = _t([[1.0, 4.0], [3.0, 4.0]])
    torch.testing.assert_close(information_gain(mean, var), _t([0.5 * math.log(1.5), 0.0]))


def test_penalty_surprise_at_lambda_prime_1_4_is_eq8_with_the_gate_on_the_penalty_magnitude():
    # r^f = -3, nll = 0.7, lam' = (1, 4): a' = 1 / (1 + e^{1 (3 - 4)}) = 0.7311,
    # r^sp = a' (nll - r^f) = 0.7311 * 3.7 = 2.7049; r^f = -0.5: a' = 1 / (1 + e^-3.5).
    got = penalty_surprise(_t([-3.0, -0.5, 0.0]), _t([0.7, -1.0, 9.0]), 1.0, 4.0)
    a3, a05 = _a(3.0, 1.0, 4.0), _a(0.5, 1.0, 4.0)
    torch.testing.assert_close(got, _t([a3 * (0.7 + 3.0), a05 * (-1.0 + 0.5), 0.0]))
    assert got[0].item() == pytest.approx(2.7049, abs=1e-4)
    # eq. 7: r^f + r^sp = a' nll + (1 - a') r^f
    assert -3.0 + got[0].item() == pytest.approx(a3 * 0.7 + (1 - a3) * -3.0, rel=1e-12)


def test_categorical_support_of_an_asymmetric_range_and_one_per_head():
    torch.testing.assert_close(
        categorical_support(_t(-2.0), _t(6.0), 5), _t([-2.0, 0.0, 2.0, 4.0, 6.0])
    )
    per_head = categorical_support(_t([-2.0, -1.0]), _t([6.0, 0.0]), 3)
    torch.testing.assert_close(per_head, _t([[-2.0, 2.0, 6.0], [-1.0, -0.5, 0.0]]))


def test_categorical_projection_by_hand_on_an_asymmetric_support():
    # atoms z = [-2, 0, 2, 4, 6] (delta 2), p = [0.1, 0.2, 0.3, 0.4, 0], r = 1, d = 0.5:
    # moved r + d z = [0, 1, 2, 3, 4] -> positions (x + 2) / 2 = [1, 1.5, 2, 2.5, 3];
    # atom 1 gets 0.1 + 0.2/2, atom 2 gets 0.2/2 + 0.3 + 0.4/2, atom 3 gets 0.4/2 (+ 0 from j=4).
    probs = _t([0.1, 0.2, 0.3, 0.4, 0.0])
    got = categorical_projection(probs, _t(1.0), _t(0.5), -2.0, 6.0)
    torch.testing.assert_close(got, _t([0.0, 0.2, 0.6, 0.2, 0.0]))
    # r = 5, d = 1: moved [3, 5, 7, 9, 11] clipped to [3, 5, 6, 6, 6] -> positions
    # [2.5, 3.5, 4, 4, 4]: atom 2 0.05, atom 3 0.05 + 0.1, atom 4 0.1 + 0.3 + 0.4.
    got = categorical_projection(probs, _t(5.0), _t(1.0), -2.0, 6.0)
    torch.testing.assert_close(got, _t([0.0, 0.0, 0.05, 0.15, 0.8]))
    # a support per head: head 1 on [-1, 0] (3 atoms, delta 0.5), r = -0.25, terminal (d = 0):
    # all of its mass moves to -0.25, position (-0.25 + 1) / 0.5 = 1.5: atoms 1 and 2 get 0.5 each.
    two = categorical_projection(
        _t([[0.2, 0.3, 0.5], [0.2, 0.3, 0.5]]),
        _t([1.0, -0.25]),
        _t([0.5, 0.0]),
        _t([-2.0, -1.0]),
        _t([6.0, 0.0]),
    )
    # head 0 on [-2, 2, 6] (delta 4): moved 1 + 0.5 z = [0, 2, 4] -> positions [0.5, 1, 1.5]:
    # atom 0 0.1, atom 1 0.1 + 0.3 + 0.25, atom 2 0.25.
    torch.testing.assert_close(two, _t([[0.1, 0.65, 0.25], [0.0, 0.5, 0.5]]))


def test_normalized_curiosity_divides_by_the_scale_floored_at_eps():
    assert normalized_curiosity(3.0, 1.5) == pytest.approx(2.0)
    assert normalized_curiosity(3.0, 0.1, eps=0.5) == pytest.approx(6.0)  # 3 / max(0.1, 0.5)
    torch.testing.assert_close(normalized_curiosity(_t([1.0, -4.0]), 4.0), _t([0.25, -1.0]))


def test_overshoot_counts_doublings_above_a_tolerance_of_3():
    assert overshoot(12.0, 3.0) == pytest.approx(2.0)  # log2(12 / 3)
    assert overshoot(4.5, 3.0) == pytest.approx(math.log2(1.5))
    assert overshoot(1.0, 3.0) == pytest.approx(-1.0)  # floored at T / 2 = 1.5
    assert overshoot(0.0, 3.0) == pytest.approx(-1.0)


def test_pid_lagrangian_with_unequal_gains_by_hand():
    # J = 2.5, d = 0.5, I = 0.3, J_prev = 1, gains (K_P, K_I, K_D) = (0.5, 0.2, 0.1), cap 0.6:
    # e = 2, I = min(0.6, 0.3 + 0.2 * 2) = 0.6, mu = 0.5 * 2 + 0.6 + 0.1 * (2.5 - 1) = 1.75.
    mu, integral = pid_lagrangian(2.5, 0.5, 0.3, 1.0, (0.5, 0.2, 0.1), 0.6)
    assert (mu, integral) == pytest.approx((1.75, 0.6))
    # no cap: I = 0.7, mu = 1 + 0.7 + 0.15 = 1.85
    assert pid_lagrangian(2.5, 0.5, 0.3, 1.0, (0.5, 0.2, 0.1)) == pytest.approx((1.85, 0.7))
    # falling cost: no derivative term; e = -0.5, I = max(0, 0.3 - 0.1) = 0.2, mu = -0.25 + 0.2 -> 0
    assert pid_lagrangian(0.0, 0.5, 0.3, 1.0, (0.5, 0.2, 0.1)) == pytest.approx((0.0, 0.2))
    # falling cost with a small proportional gain: mu = 0.1 * -0.5 + 0.2 = 0.15
    assert pid_lagrangian(0.0, 0.5, 0.3, 1.0, (0.1, 0.2, 3.0)) == pytest.approx((0.15, 0.2))


def test_running_mean_update_with_a_rate_floor_above_one_over_k():
    # s = 2 after 3 batches, x = 6: k = 4, alpha = max(1/4, 0.3) = 0.3 -> 2 + 0.3 * 4 = 3.2
    assert running_mean_update(2.0, 3, 6.0, min_rate=0.3) == (pytest.approx(3.2), 4)
    # alpha = max(1/4, 0.1) = 0.25 -> 3.0
    assert running_mean_update(2.0, 3, 6.0, min_rate=0.1) == (pytest.approx(3.0), 4)
    # the first batch is taken whole (alpha = 1)
    assert running_mean_update(7.0, 0, 1.5) == (pytest.approx(1.5), 1)


def test_tolerance_unit_with_a_non_default_lambda2():
    assert tolerance_unit(6.0, 3.0) == pytest.approx(2.0)
    assert tolerance_unit(6.0) == pytest.approx(3.0)  # lambda_2 = 2 by default
