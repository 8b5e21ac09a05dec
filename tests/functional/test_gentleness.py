"""The paper's gentleness equations against hand-computed numbers, plus property tests."""

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from gentlerl.functional import (
    acceptability,
    force_penalty,
    gaussian_nll,
    gaussian_nll_parts,
    impact,
    impact_penalty,
    information_gain,
    mixture_moments,
    penalty_surprise,
    torque_penalty,
)

# |x| <= 2**50 ~ 1.1e15: far beyond any physical force (N) or log-density, inside the documented range.
finite = st.floats(min_value=-(2.0**50), max_value=2.0**50, allow_nan=False, width=32)


def test_impact_sums_force_increases_over_channels_only():
    force = torch.tensor([[1.0, 2.0, 0.0], [3.0, 0.0, 0.0]])
    next_force = torch.tensor([[2.5, 1.0, 0.5], [0.0, 0.0, 0.0]])
    # site 0: +1.5 (normal) + 0 (decrease ignored) + 0.5 = 2.0; site 1: only decreases → 0.
    torch.testing.assert_close(impact(force, next_force), torch.tensor([2.0, 0.0]))


def test_impact_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="same shape"):
        impact(torch.zeros(5, 3), torch.zeros(5, 2))
    with pytest.raises(ValueError, match="n_sites, n_channels"):
        impact(torch.zeros(3), torch.zeros(3))


def test_acceptability_is_the_papers_sigmoid():
    # a(m) = 1 / (1 + exp(l1 (m - l2))): at m = l2 it is 1/2, at m = 1 with l = [2, 2] it is 1/(1+e^-2).
    x = torch.tensor([2.0, 1.0, 3.0])
    expected = torch.tensor([0.5, 1 / (1 + math.exp(-2)), 1 / (1 + math.exp(2))])
    torch.testing.assert_close(acceptability(x, 2.0, 2.0), expected)
    with pytest.raises(ValueError, match="lam1"):
        acceptability(x, -1.0, 2.0)


def test_impact_penalty_matches_hand_computed_numbers():
    # 1 N at one fingertip → -(1 - sigmoid(2)) = -0.1192; 2 N → -(1 - 0.5) * 2 = -1.0.
    one = impact_penalty(torch.tensor([1.0, 0.0, 0.0, 0.0, 0.0]))
    two = impact_penalty(torch.tensor([0.0, 2.0, 0.0, 0.0, 0.0]))
    assert one.item() == pytest.approx(-0.1192, abs=1e-4)
    assert two.item() == pytest.approx(-1.0, abs=1e-6)
    # Sites add up: both at once.
    both = impact_penalty(torch.tensor([1.0, 2.0, 0.0, 0.0, 0.0]))
    assert both.item() == pytest.approx(-1.1192, abs=1e-4)


def test_force_penalty_charges_the_total_force_past_lambda2():
    # Site 0 holds 5.02 + 0.44 + 0.84 = 6.3 N (the touch task's straight press): with l = [2, 8]
    # a = sigmoid(2 (8 - 6.3)) = sigmoid(3.4), cost (1 - a) 6.3 = 0.2035. 8 N costs half: -4.
    force = torch.zeros(2, 5, 3)
    force[0, 0] = torch.tensor([5.02, 0.44, 0.84])
    force[1, 1, 0] = 8.0
    expected = torch.tensor([-(1 - 1 / (1 + math.exp(-3.4))) * 6.3, -4.0])
    torch.testing.assert_close(force_penalty(force), expected)
    # Same number as the impact penalty of a press from zero: the level is charged like eq. 4.
    torch.testing.assert_close(force_penalty(force, 2.0, 2.0), impact_penalty(force.sum(-1)))
    with pytest.raises(ValueError, match="n_sites, n_channels"):
        force_penalty(torch.zeros(3))


def test_torque_penalty_charges_effort_magnitudes_past_lambda2():
    # l = [4, 1]: 0.5 N m costs (1 - sigmoid(2)) 0.5 = 0.0596 whatever its sign; 1 N m costs 0.5.
    torque = torch.tensor([[0.5, -0.5, 0.0], [1.0, 0.0, 0.0]])
    cost = (1 - 1 / (1 + math.exp(-2))) * 0.5
    torch.testing.assert_close(torque_penalty(torque), torch.tensor([-2 * cost, -0.5]))
    with pytest.raises(ValueError, match="n_actuators"):
        torque_penalty(torch.tensor(1.0))


def test_mixture_moments_of_two_members():
    # Members N(0, 1) and N(2, 3): mu* = 1, var* = mean(var) + mean((mu - mu*)^2) = 2 + 1 = 3.
    mean = torch.tensor([[0.0], [2.0]])
    var = torch.tensor([[1.0], [3.0]])
    mu, v = mixture_moments(mean, var, dim=0)
    torch.testing.assert_close(mu, torch.tensor([1.0]))
    torch.testing.assert_close(v, torch.tensor([3.0]))
    # The paper's form: mean(var + mu^2) - mu*^2 = (1 + 0 + 3 + 4) / 2 - 1 = 3.
    torch.testing.assert_close(v, (var + mean**2).mean(0) - mu**2)


def test_gaussian_nll_standard_normal():
    # -log N(1 | 0, 1) = 0.5 log(2 pi) + 0.5 = 1.4189.
    out = gaussian_nll(torch.tensor([0.0, 1.0]), torch.zeros(2), torch.ones(2))
    torch.testing.assert_close(out, torch.tensor([0.5 * math.log(2 * math.pi), 1.4189385]))
    # Variance 4 at x = mean: 0.5 log(2 pi 4) = 1.6121.
    assert gaussian_nll(torch.tensor(3.0), torch.tensor(3.0), torch.tensor(4.0)).item() == (
        pytest.approx(0.5 * math.log(8 * math.pi))
    )


def test_gaussian_nll_parts_are_the_spread_and_the_error_and_sum_to_it():
    # x = 3 under N(1, 4): spread 0.5 log(8 pi) = 1.6121, error 0.5 * 4 / 4 = 0.5.
    spread, error = gaussian_nll_parts(torch.tensor(3.0), torch.tensor(1.0), torch.tensor(4.0))
    assert spread.item() == pytest.approx(0.5 * math.log(8 * math.pi))
    assert error.item() == pytest.approx(0.5)
    x, mean, var = torch.randn(50), torch.randn(50), torch.rand(50) + 1e-3
    torch.testing.assert_close(sum(gaussian_nll_parts(x, mean, var)), gaussian_nll(x, mean, var))
    with pytest.raises(ValueError, match="min_var"):
        gaussian_nll_parts(x, mean, var, min_var=0.0)


def test_gaussian_nll_floors_collapsed_variance():
    out = gaussian_nll(torch.tensor(1.0), torch.tensor(0.0), torch.tensor(0.0), min_var=1e-6)
    assert torch.isfinite(out)
    assert out.item() == pytest.approx(0.5 * (math.log(2 * math.pi * 1e-6) + 1e6), rel=1e-6)


def test_penalty_surprise_hand_computed():
    # r^f = -1 (a 2 N impact), nll = 0.5, l' = [2, 2]: a' = sigmoid(2 (2 - 1)) = 0.8808,
    # r^sp = 0.8808 * (0.5 - (-1)) = 1.3212; r^f + r^sp = a' nll + (1 - a') r^f = 0.3212.
    penalty = torch.tensor([-1.0, 0.0])
    nll = torch.tensor([0.5, 7.0])
    out = penalty_surprise(penalty, nll, 2.0, 2.0)
    a = 1 / (1 + math.exp(-2))
    torch.testing.assert_close(out, torch.tensor([a * 1.5, 0.0]))
    assert (out[0] + penalty[0]).item() == pytest.approx(a * 0.5 + (1 - a) * -1.0, abs=1e-6)


def test_penalty_surprise_higher_lam2_accepts_larger_penalties():
    penalty = torch.tensor([-3.0])
    nll = torch.tensor([1.0])
    low = penalty_surprise(penalty, nll, 2.0, 1.0)
    high = penalty_surprise(penalty, nll, 2.0, 4.0)
    assert high.item() > low.item() > 0


@settings(max_examples=200, deadline=None)
@given(st.lists(finite, min_size=6, max_size=6), st.lists(finite, min_size=6, max_size=6))
def test_impact_is_non_negative_and_penalty_non_positive(f, g):
    force = torch.tensor(f).view(2, 3)
    next_force = torch.tensor(g).view(2, 3)
    m = impact(force, next_force)
    assert (m >= 0).all()
    p = impact_penalty(m)
    assert torch.isfinite(p) and p.item() <= 0
    # Forces are magnitudes (>= 0); actuator efforts have either sign: both penalties are <= 0.
    for penalty in (force_penalty(force.abs()), torque_penalty(next_force)):
        assert torch.isfinite(penalty).all() and (penalty <= 0).all()


@settings(max_examples=200, deadline=None)
@given(finite, finite)
def test_penalty_surprise_is_zero_without_penalty_and_finite(nll, lam2):
    zero = penalty_surprise(torch.tensor(0.0), torch.tensor(nll), 2.0, abs(lam2))
    assert zero.item() == 0.0
    neg = penalty_surprise(torch.tensor(-abs(nll) - 1e-3), torch.tensor(nll), 2.0, abs(lam2))
    assert torch.isfinite(neg)


@settings(max_examples=200, deadline=None)
@given(finite, finite, st.floats(min_value=0.0, max_value=2.0**50, width=32))
def test_gaussian_nll_and_mixture_are_finite(x, mu, var):
    assert torch.isfinite(gaussian_nll(torch.tensor(x), torch.tensor(mu), torch.tensor(var)))
    mean = torch.tensor([[x], [mu]])
    variance = torch.tensor([[var], [0.0]])
    m, v = mixture_moments(mean, variance)
    assert torch.isfinite(m).all() and torch.isfinite(v).all() and (v >= 0).all()


NON_FINITE = (float("nan"), float("inf"), float("-inf"))


def test_impact_penalty_is_never_positive_even_for_a_negative_impact():
    # An impact is never negative (eq. 1); a negative value counts as no impact. Before, -5 N gave
    # -(1 - sigmoid(2 * 7)) * -5 = +4e-6.
    assert impact_penalty(torch.tensor([-5.0])).item() == 0.0
    assert impact_penalty(torch.tensor([-5.0, 1.0])).item() == pytest.approx(-0.1192, abs=1e-4)


@settings(max_examples=200, deadline=None)
@given(st.lists(finite, min_size=5, max_size=5), finite, st.floats(0.0, 2.0**50, width=32))
def test_impact_penalty_is_non_positive_for_every_finite_input(m, lam2, lam1):
    assert impact_penalty(torch.tensor(m), lam1, lam2).item() <= 0.0


@pytest.mark.parametrize("bad", NON_FINITE)
def test_non_finite_force_or_impact_never_gives_a_finite_penalty(bad):
    force = torch.zeros(2, 5, 3)
    next_force = torch.ones(2, 5, 3)
    next_force[0, 2, 1] = bad
    m = impact(force, next_force)
    assert not torch.isfinite(m[0, 2]) and torch.isfinite(m[1]).all()
    p = impact_penalty(m)
    assert not torch.isfinite(p[0]) and torch.isfinite(p[1])
    force[1, 0, 0] = bad  # the previous force is as dangerous as the next one
    assert not torch.isfinite(impact_penalty(impact(force, next_force))).any()


@pytest.mark.parametrize("bad", NON_FINITE)
def test_penalty_surprise_of_a_non_finite_penalty_or_nll_is_not_finite(bad):
    # NaN < 0 is False: eq. 8's "otherwise 0" branch used to turn a NaN penalty into reward 0.
    assert not torch.isfinite(penalty_surprise(torch.tensor(bad), torch.tensor(1.0)))
    for penalty in (0.0, -1.0):
        assert not torch.isfinite(penalty_surprise(torch.tensor(penalty), torch.tensor(bad)))
    assert penalty_surprise(torch.tensor(0.0), torch.tensor(1.0)).item() == 0.0


@pytest.mark.parametrize("bad", NON_FINITE)
def test_gaussian_nll_and_mixture_of_non_finite_inputs_are_not_finite(bad):
    one, b = torch.tensor(1.0), torch.tensor(bad)
    for x, mu, var in ((b, one, one), (one, b, one), (one, one, b)):
        assert not torch.isfinite(gaussian_nll(x, mu, var)), (x, mu, var)
    mean, var = mixture_moments(torch.tensor([[1.0], [bad]]), torch.ones(2, 1))
    assert not torch.isfinite(gaussian_nll(one, mean, var))
    mean, var = mixture_moments(torch.ones(2, 1), torch.tensor([[1.0], [bad]]))
    assert not torch.isfinite(gaussian_nll(one, mean, var))


def test_information_gain_is_zero_when_the_members_agree_and_grows_with_their_disagreement():
    var = torch.full((4, 3), 0.5)
    agree = torch.ones(4, 3)
    torch.testing.assert_close(information_gain(agree, var), torch.zeros(3))
    # Means -1, 1, -1, 1: epistemic 1, aleatoric 0.5 -> 1/2 log(1 + 1 / 0.5) = 1/2 log 3.
    split = torch.tensor([-1.0, 1.0, -1.0, 1.0]).unsqueeze(-1).expand(4, 3)
    torch.testing.assert_close(information_gain(split, var), torch.full((3,), 0.5 * math.log(3)))
    # Same disagreement, wider members: less to learn.
    assert (information_gain(split, 4 * var) < information_gain(split, var)).all()


def test_torque_penalty_of_one_hand_without_batch_dims():
    # [n_actuators] alone: 2 N m with l = [4, 1] costs (1 - sigmoid(4 (1 - 2))) 2 = 1.964 (eq. 4).
    out = torque_penalty(torch.tensor([2.0, 0.0]))
    assert out.shape == () and out.item() == pytest.approx(-(1 - 1 / (1 + math.exp(4))) * 2)


def test_mixture_moments_are_taken_per_batch_entry():
    # Eq. 5 for each entry on its own. Members along dim 0, two entries along dim 1:
    # entry 0: N(0, 1), N(2, 3) -> mu* = 1, var* = 2 + 1 = 3;
    # entry 1: N(5, 1), N(5, 1) -> mu* = 5, var* = 1 + 0 = 1.
    mean = torch.tensor([[0.0, 5.0], [2.0, 5.0]])
    var = torch.tensor([[1.0, 1.0], [3.0, 1.0]])
    mu, v = mixture_moments(mean, var)
    torch.testing.assert_close(mu, torch.tensor([1.0, 5.0]))
    torch.testing.assert_close(v, torch.tensor([3.0, 1.0]))
    # The same ensemble along dim 1.
    mu, v = mixture_moments(mean.T, var.T, dim=1)
    torch.testing.assert_close(v, torch.tensor([3.0, 1.0]))


def test_mixture_moments_refuse_means_and_variances_of_different_shapes():
    with pytest.raises(ValueError, match=r"same shape, got \(2, 3\) and \(2, 4\)"):
        mixture_moments(torch.zeros(2, 3), torch.ones(2, 4))


def test_gaussian_nll_refuses_a_variance_floor_that_is_not_positive():
    # The floor exists so that log(sigma^2) is finite: 0 would let a collapsed variance through.
    for bad in (0.0, -1e-6):
        with pytest.raises(ValueError, match=r"min_var must be > 0, got"):
            gaussian_nll(torch.tensor(1.0), torch.tensor(0.0), torch.tensor(1.0), min_var=bad)


def test_information_gain_is_taken_per_entry_and_along_the_members_dim():
    # Entry 0: means -1, 1 (epistemic 1), variances 0.5 -> 1/2 log(1 + 1 / 0.5) = 1/2 log 3.
    # Entry 1: means 0, 0, variances 2 -> 0. Entry 2: means -1, 1, variances 2 -> 1/2 log 1.5.
    mean = torch.tensor([[-1.0, 0.0, -1.0], [1.0, 0.0, 1.0]])
    var = torch.tensor([[0.5, 2.0, 2.0], [0.5, 2.0, 2.0]])
    expected = torch.tensor([0.5 * math.log(3), 0.0, 0.5 * math.log(1.5)])
    torch.testing.assert_close(information_gain(mean, var), expected)
    # Members along dim 1 (e.g. [batch, members]): the same numbers.
    torch.testing.assert_close(information_gain(mean.T, var.T, dim=1), expected)


def test_penalty_surprise_defaults_are_the_papers_lambda_prime():
    # lambda' = [2, 2] by default (eq. 8): r^f = -1, nll = 0.5 -> sigmoid(2 (2 - 1)) * 1.5;
    # r^f = -3, nll = 1 -> sigmoid(2 (2 - 3)) * 4.
    out = penalty_surprise(torch.tensor([-1.0, -3.0]), torch.tensor([0.5, 1.0]))
    expected = torch.tensor([1.5 / (1 + math.exp(-2)), 4.0 / (1 + math.exp(2))])
    torch.testing.assert_close(out, expected)
