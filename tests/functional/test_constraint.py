"""The Method III equations, each against numbers computed by hand."""

import math

import pytest
import torch

from gentlerl.functional import (
    impact_penalty,
    normalized_curiosity,
    overshoot,
    pid_lagrangian,
    running_mean_update,
    tolerance_unit,
)


def test_the_tolerance_rule_reads_impacts_in_units_of_half_the_tolerance():
    assert tolerance_unit(2.0) == 1.0  # the paper's hand: unchanged
    assert tolerance_unit(20.0) == 10.0
    # An impact at the tolerance costs -1 on every env: (1 - sigmoid(0)) * 2.
    for tolerance in (2.0, 20.0, 300.0):
        m = torch.tensor([tolerance]) / tolerance_unit(tolerance)
        assert impact_penalty(m).item() == pytest.approx(-1.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan])
def test_the_tolerance_rule_refuses_a_tolerance_that_is_not_a_positive_impact(bad):
    with pytest.raises(ValueError, match="tolerance must be a finite impact > 0"):
        tolerance_unit(bad)


def test_the_running_scale_is_the_plain_mean_then_an_exponential_average():
    mean, count = 0.0, 0
    for x in (4.0, 2.0, 6.0):  # 1/k rates: the plain mean, 4.0
        mean, count = running_mean_update(mean, count, x, min_rate=0.25)
    assert (mean, count) == (pytest.approx(4.0), 3)
    mean, count = running_mean_update(mean, count, 8.0, min_rate=0.25)  # rate 1/4 = min
    assert mean == pytest.approx(5.0)  # 4 + (8 - 4) / 4
    mean, count = running_mean_update(mean, count, 0.0, min_rate=0.25)  # rate stays 1/4
    assert mean == pytest.approx(3.75)  # 5 - 5 / 4


def test_normalized_curiosity_divides_by_the_running_scale_floored():
    assert normalized_curiosity(30.0, 15.0) == pytest.approx(2.0)
    assert normalized_curiosity(torch.tensor([-3.0]), 1.5).item() == pytest.approx(-2.0)
    assert normalized_curiosity(1.0, 0.0, eps=0.5) == pytest.approx(2.0)


def test_the_pid_multiplier_by_hand():
    gains = (1.0, 0.1, 0.5)
    # cost 3 against a limit of 1: e = 2, I = 0.2, derivative on the rise 3 - 1 = 2.
    mu, integral = pid_lagrangian(3.0, 1.0, 0.0, 1.0, gains)
    assert integral == pytest.approx(0.2) and mu == pytest.approx(2.0 + 0.2 + 1.0)
    # cost falls to 0.5: e = -0.5, I = 0.15, no derivative on a fall, mu = max(0, -0.35).
    mu, integral = pid_lagrangian(0.5, 1.0, integral, 3.0, gains)
    assert integral == pytest.approx(0.15) and mu == 0.0
    # a long stretch below the limit drains the integral to 0, never below
    for _ in range(2):  # 0.15 - 0.1 = 0.05, then max(0, 0.05 - 0.1) = 0
        mu, integral = pid_lagrangian(0.0, 1.0, integral, 0.5, gains)
    assert integral == 0.0 and mu == 0.0


def test_the_pid_integral_is_capped_by_integral_max():
    # anti-windup: e = 2 per step with K_I = 1 would store 2, 4, 6; capped at 3 it stores 2, 3, 3
    gains, integral = (0.0, 1.0, 0.0), 0.0
    stored = []
    for _ in range(3):
        mu, integral = pid_lagrangian(2.0, 0.0, integral, 2.0, gains, integral_max=3.0)
        stored.append(integral)
    assert stored == [2.0, 3.0, 3.0] and mu == 3.0
    # one step below the limit drains it at once by K_I e: 3 - 1 = 2 (uncapped: 6 - 1 = 5)
    assert pid_lagrangian(-1.0, 0.0, integral, 2.0, gains, integral_max=3.0) == (2.0, 2.0)
    with pytest.raises(ValueError, match="integral_max must be >= 0"):
        pid_lagrangian(1.0, 0.0, 0.0, 1.0, gains, integral_max=-1.0)


def test_the_pid_multiplier_refuses_a_negative_gain():
    with pytest.raises(
        ValueError, match="gains must be .K_P, K_I, K_D., each a finite number >= 0"
    ):
        pid_lagrangian(1.0, 1.0, 0.0, 1.0, (1.0, -0.1, 0.0))


def test_the_overshoot_is_doublings_above_the_tolerance_floored_at_half_of_it():
    assert overshoot(2.0, 2.0) == 0.0
    assert overshoot(8.0, 2.0) == 2.0  # two doublings
    assert overshoot(1.0, 2.0) == overshoot(0.0, 2.0) == -1.0  # half or less, no contact
    with pytest.raises(ValueError, match="tolerance must be a finite impact > 0"):
        overshoot(1.0, 0.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"gains": (math.nan, 0.1, 0.0)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"gains": (1.0, math.inf, 0.0)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"gains": (True, 0.1, 0.0)}, r"gains must be \[K_P, K_I, K_D\], each a finite number >= 0"),
        ({"gains": (1.0, 0.1)}, r"gains must be \[K_P, K_I, K_D\]"),
        ({"cost": math.nan}, "cost must be a finite number, got nan"),
        ({"limit": math.inf}, "limit must be a finite number, got inf"),
        ({"integral": math.nan}, "integral must be a finite number, got nan"),
        ({"previous_cost": -math.inf}, "previous_cost must be a finite number, got -inf"),
        ({"integral_max": math.nan}, "integral_max must be >= 0"),
    ],
)  # fmt: skip
def test_the_pid_multiplier_refuses_a_non_finite_number_or_a_bool_naming_it(kwargs, message):
    args = {"cost": 1.0, "limit": 0.0, "integral": 0.0, "previous_cost": 1.0}
    args["gains"] = (1.0, 0.1, 0.0)
    with pytest.raises(ValueError, match=message):
        pid_lagrangian(**{**args, **kwargs})


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: tolerance_unit(True), "tolerance must be a finite impact > 0"),
        (lambda: tolerance_unit(2.0, math.inf), "lam2 must be a finite number > 0, got inf"),
        (lambda: tolerance_unit(2.0, math.nan), "lam2 must be a finite number > 0, got nan"),
        (lambda: overshoot(math.nan, 2.0), "impact must be a finite number >= 0, got nan"),
        (lambda: overshoot(-1.0, 2.0), "impact must be a finite number >= 0, got -1.0"),
        (lambda: overshoot(1.0, True), "tolerance must be a finite impact > 0"),
        (lambda: running_mean_update(math.nan, 1, 2.0), "mean must be a finite number, got nan"),
        (lambda: running_mean_update(1.0, 1, math.inf), "batch_mean must be a finite number, got inf"),
        (lambda: running_mean_update(1.0, -1, 2.0), "count must be an integer >= 0, got -1"),
        (lambda: running_mean_update(1.0, True, 2.0), "count must be an integer >= 0, got True"),
        (lambda: normalized_curiosity(1.0, math.nan), "scale must be a finite number, got nan"),
    ],
)  # fmt: skip
def test_the_method3_equations_refuse_a_non_finite_or_boolean_number_naming_it(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_the_tolerance_rule_holds_below_one_newton_and_for_any_positive_lambda2():
    # u = T / lambda_2 for every T > 0 and lambda_2 > 0, not only for values above 1.
    assert tolerance_unit(0.5) == 0.25  # a fragile object: impacts read in units of 0.25 N
    assert tolerance_unit(2.0, lam2=0.5) == 4.0
    assert overshoot(1.0, 0.5) == 1.0  # one doubling above a 0.5 N tolerance
    assert overshoot(0.5, 0.5) == 0.0


@pytest.mark.parametrize("lam2", [0.0, -2.0])
def test_the_tolerance_rule_refuses_a_lambda2_that_is_not_positive(lam2):
    # u = T / lambda_2: lambda_2 = 0 divides by zero, a negative one flips the penalty's unit.
    with pytest.raises(ValueError, match=r"lam2 must be a finite number > 0, got"):
        tolerance_unit(2.0, lam2=lam2)


def test_the_running_scale_rate_floors_at_one_percent_by_default():
    # alpha_k = max(1/k, alpha_min), alpha_min = 0.01: the first batch is the scale itself ...
    assert running_mean_update(0.0, 0, 5.0) == (5.0, 1)
    # ... and from the 100th batch on each moves it 1 % of the way: 1 + 0.01 (3 - 1) = 1.02.
    mean, count = running_mean_update(1.0, 150, 3.0)
    assert (mean, count) == (pytest.approx(1.02), 151)


def test_the_running_scale_rate_may_be_one_and_no_more():
    # alpha_min = 1: s_k = x_k, the last batch's magnitude alone (the interval is (0, 1]).
    assert running_mean_update(2.0, 5, 4.0, min_rate=1.0) == (4.0, 6)
    for bad in (0.0, -0.5, 1.5):
        with pytest.raises(ValueError, match=r"min_rate must be in \(0, 1\]"):
            running_mean_update(2.0, 5, 4.0, min_rate=bad)


def test_normalized_curiosity_floors_the_scale_at_a_millionth_by_default():
    # nll / max(s, 1e-6): a scale of 0.5 divides (1 / 0.5 = 2), a zero scale is floored at 1e-6.
    assert normalized_curiosity(1.0, 0.5) == 2.0
    assert normalized_curiosity(1.0, 0.0) == pytest.approx(1e6)


def test_the_pid_integral_cap_may_be_zero_or_below_one():
    gains = (1.0, 1.0, 0.0)
    # integral_max = 0: I_k = min(0, max(0, 0 + 1 * 2)) = 0, a pure P controller: mu = K_P e = 2.
    assert pid_lagrangian(3.0, 1.0, 0.0, 3.0, gains, integral_max=0.0) == (2.0, 0.0)
    # integral_max = 0.5: I_k = min(0.5, 2) = 0.5, mu = 2 + 0.5.
    assert pid_lagrangian(3.0, 1.0, 0.0, 3.0, gains, integral_max=0.5) == (2.5, 0.5)
