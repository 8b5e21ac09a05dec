"""Properties of every equation in gentlerl.functional, for any input hypothesis draws: signs,
ranges, monotonicity, the special cases the paper states, and each formula against a direct
computation (float64, so that the comparisons need no float32 tolerance).

The direct computations are the paper's formulas written out here with ``math`` (eq. 3's
sigmoid is :func:`_paper_acceptability`), never the module's own helpers: a property that took
``acceptability`` from the code under test would pass with its bug. Swapping lambda_1 and
lambda_2, squaring the impact or doubling the penalty each fail them.
"""

import math

import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from gentlerl.functional import (
    acceptability,
    categorical_projection,
    force_penalty,
    gaussian_nll,
    impact,
    impact_penalty,
    mixture_moments,
    overshoot,
    penalty_surprise,
    pid_lagrangian,
    tolerance_unit,
    torque_penalty,
)

#: Few examples per property: the whole file runs in a few seconds on a busy CPU.
FEW = settings(max_examples=40, deadline=None)
forces = st.floats(0.0, 100.0, allow_nan=False)
lams = st.tuples(st.floats(0.1, 5.0), st.floats(0.0, 10.0))


def _t(values) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float64)


def _paper_acceptability(x: float, lam1: float, lam2: float) -> float:
    """Eq. 3 as the paper writes it: a(x) = 1 / (1 + exp(lambda_1 (x - lambda_2)))."""
    z = lam1 * (x - lam2)
    return 0.0 if z > 700 else 1.0 / (1.0 + math.exp(z))


def _paper_penalty(amounts: list[float], lam1: float, lam2: float) -> float:
    """Eq. 4 as the paper writes it: r^f = -sum_i (1 - a(m_i)) m_i."""
    return -sum((1.0 - _paper_acceptability(m, lam1, lam2)) * m for m in amounts)


@FEW
@given(
    st.integers(1, 5).flatmap(
        lambda n_sites: st.lists(
            st.lists(st.tuples(forces, forces), min_size=n_sites, max_size=n_sites),
            min_size=1,
            max_size=4,
        )
    )
)
def test_impact_is_eq1_per_site_never_negative_and_zero_where_the_force_does_not_rise(channels):
    # channels[c][i] = (f^{i,c}_t, f^{i,c}_{t+1}) for sites i and channels c: [n_sites, n_channels]
    force = _t([[c[i][0] for c in channels] for i in range(len(channels[0]))])
    next_force = _t([[c[i][1] for c in channels] for i in range(len(channels[0]))])
    m = impact(force, next_force)
    assert m.shape == (len(channels[0]),) and (m >= 0).all()
    for i in range(len(channels[0])):
        rising = sum(max(0.0, c[i][1] - c[i][0]) for c in channels)
        assert math.isclose(m[i].item(), rising, rel_tol=1e-12, abs_tol=1e-12)
    falling = torch.minimum(force, next_force)
    assert (impact(force, falling) == 0.0).all()


@FEW
@given(lams, forces, forces)
def test_acceptability_is_eq3_in_0_1_and_falls_as_the_amount_grows(lam, a, b):
    low, high = sorted((a, b))
    lam1, lam2 = lam
    values = acceptability(_t([low, high]), lam1, lam2)
    for got, x in zip(values.tolist(), (low, high), strict=True):
        assert math.isclose(got, _paper_acceptability(x, lam1, lam2), rel_tol=1e-9, abs_tol=1e-12)
    assert values[0] >= values[1]  # monotone decreasing in m
    assert ((values >= 0) & (values <= 1)).all()
    # strictly inside (0, 1) wherever the sigmoid's argument is not saturated in float64
    moderate = _t([low, high])[(lam1 * (lam2 - _t([low, high]))).abs() < 30]
    inner = acceptability(moderate, lam1, lam2)
    assert ((inner > 0) & (inner < 1)).all()


#: Impacts at 1-5 sites of one step.
sites = st.lists(forces, min_size=1, max_size=5)


@FEW
@given(lams, sites, sites)
def test_the_impact_penalty_is_eq4_over_sites_never_positive_and_grows_with_the_impact(
    lam, impacts, more
):
    lam1, lam2 = lam
    penalty = impact_penalty(_t(impacts), lam1, lam2).item()
    assert math.isclose(penalty, _paper_penalty(impacts, lam1, lam2), rel_tol=1e-9, abs_tol=1e-9)
    assert penalty <= 0
    # a larger impact at every site costs at least as much
    larger = [m + extra for m, extra in zip(impacts, more, strict=False)] + impacts[len(more) :]
    assert impact_penalty(_t(larger), lam1, lam2).item() <= penalty + 1e-9
    assert impact_penalty(_t([0.0] * len(impacts)), lam1, lam2).item() == 0.0


@FEW
@given(lams, st.lists(st.lists(forces, min_size=3, max_size=3), min_size=1, max_size=5))
def test_the_force_penalty_is_eq4_of_each_sites_channel_sum(lam, force):
    lam1, lam2 = lam
    got = force_penalty(_t(force), lam1, lam2).item()
    expected = _paper_penalty([sum(channels) for channels in force], lam1, lam2)
    assert math.isclose(got, expected, rel_tol=1e-9, abs_tol=1e-9)


@FEW
@given(lams, st.lists(st.floats(-20.0, 20.0), min_size=1, max_size=8))
def test_the_torque_penalty_is_eq4_of_the_effort_magnitudes(lam, torque):
    lam1, lam2 = lam
    got = torque_penalty(_t(torque), lam1, lam2).item()
    expected = _paper_penalty([abs(t) for t in torque], lam1, lam2)
    assert math.isclose(got, expected, rel_tol=1e-9, abs_tol=1e-9)


@FEW
@given(
    st.floats(-50, 50), st.floats(1e-3, 50), st.integers(1, 7), st.integers(1, 4)
)  # fmt: skip
def test_the_mixture_of_identical_members_is_the_member(mean, var, members, features):
    mu, sigma2 = mixture_moments(
        torch.full((members, features), mean, dtype=torch.float64),
        torch.full((members, features), var, dtype=torch.float64),
    )
    assert torch.allclose(mu, _t([mean] * features))
    assert torch.allclose(sigma2, _t([var] * features))


@FEW
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(0.0, 50)), min_size=1, max_size=6))
def test_the_mixture_variance_is_never_below_the_members_mean_variance(members):
    mean, var = _t([m[0] for m in members]), _t([m[1] for m in members])
    mu, sigma2 = mixture_moments(mean, var)
    assert math.isclose(mu.item(), mean.mean().item(), abs_tol=1e-12)
    assert sigma2.item() >= var.mean().item() - 1e-12


@FEW
@given(st.floats(-100, 100), st.floats(-100, 100), st.floats(0.0, 100.0))
def test_the_gaussian_nll_is_the_direct_formula_with_the_variance_floored(x, mean, var):
    nll = gaussian_nll(_t([x]), _t([mean]), _t([var])).item()
    floored = max(var, 1e-6)
    direct = 0.5 * math.log(2 * math.pi * floored) + (x - mean) ** 2 / (2 * floored)
    assert math.isclose(nll, direct, rel_tol=1e-9, abs_tol=1e-9)


@FEW
@given(st.floats(-1e3, 1e3), lams, st.floats(-10.0, 0.0))
def test_penalty_surprise_is_zero_without_contact_and_eq7_with_it(nll, lam, penalty):
    # r^f == 0 (no contact): nothing, whatever the model says.
    assert penalty_surprise(_t([0.0]), _t([nll]), *lam).item() == 0.0
    # r^f < 0: r^f + r^sp is eq. 7's convex combination a' nll + (1 - a') r^f.
    if penalty < 0:
        a = _paper_acceptability(-penalty, *lam)  # a' reads the penalty's magnitude
        total = penalty + penalty_surprise(_t([penalty]), _t([nll]), *lam).item()
        assert math.isclose(total, a * nll + (1 - a) * penalty, rel_tol=1e-9, abs_tol=1e-9)
        surprise = penalty_surprise(_t([penalty]), _t([nll]), *lam).item()
        assert math.isclose(surprise, a * (nll - penalty), rel_tol=1e-9, abs_tol=1e-9)


@FEW
@given(
    st.lists(st.floats(0.0, 1.0), min_size=2, max_size=21).filter(lambda p: sum(p) > 1e-3),
    st.floats(0.0, 1.0),
    st.floats(-1.0, 1.0),
)
def test_the_categorical_projection_keeps_mass_and_mean_within_the_support(
    weights, discount, share
):
    v_min, v_max = -10.0, 10.0
    probs = _t(weights) / sum(weights)
    reward = share * v_max * (1 - discount)  # every moved atom stays within the support
    projected = categorical_projection(probs, _t(reward), _t(discount), v_min, v_max)
    atoms = torch.linspace(v_min, v_max, len(weights), dtype=torch.float64)
    assert (projected >= 0).all() and math.isclose(projected.sum().item(), 1.0, rel_tol=1e-9)
    expected = reward + discount * (probs * atoms).sum().item()
    assert math.isclose((projected * atoms).sum().item(), expected, abs_tol=1e-9)


@FEW
@given(
    st.lists(st.floats(0.0, 1.0), min_size=2, max_size=11).filter(lambda p: sum(p) > 1e-3),
    st.floats(-1e3, 1e3),
    st.floats(0.0, 1.0),
)
def test_the_categorical_projection_keeps_mass_whatever_the_reward(weights, reward, discount):
    probs = _t(weights) / sum(weights)
    projected = categorical_projection(probs, _t(reward), _t(discount), -10.0, 10.0)
    assert (projected >= 0).all() and math.isclose(projected.sum().item(), 1.0, rel_tol=1e-9)


@FEW
@given(st.floats(1e-3, 1e6), st.floats(0.1, 10.0), st.floats(0.0, 1e7))
def test_the_tolerance_rule_and_the_overshoot(tolerance, lam2, impact_value):
    assert math.isclose(tolerance_unit(tolerance, lam2) * lam2, tolerance)
    assert overshoot(tolerance, tolerance) == 0.0
    doublings = overshoot(impact_value, tolerance)
    assert doublings >= -1.0  # floored at half the tolerance
    assert overshoot(impact_value * 2 + tolerance, tolerance) >= doublings  # monotone


@FEW
@given(
    st.lists(st.floats(-1.0, 20.0), min_size=1, max_size=30),
    st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 10.0), st.floats(0.0, 10.0)),
    st.floats(0.0, 50.0),
)
def test_the_pid_multiplier_is_never_negative_and_its_integral_stays_within_its_cap(
    costs, gains, integral_max
):
    integral, previous = 0.0, costs[0]
    for cost in costs:
        mu, integral = pid_lagrangian(cost, 0.0, integral, previous, gains, integral_max)
        assert mu >= 0.0 and 0.0 <= integral <= integral_max
        previous = cost
    # with the integral term alone the multiplier is the integral: bounded by its cap
    mu, integral = pid_lagrangian(
        costs[-1], 0.0, integral, previous, (0.0, gains[1], 0.0), integral_max
    )
    assert mu == integral <= integral_max
