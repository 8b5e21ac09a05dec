"""``GentlenessConfig``: the paper's defaults and the checks a group built in Python gets."""

import pytest

from gentlerl.config import GentlenessConfig
from gentlerl.config.rules import check_group


def test_the_defaults_are_the_papers_setting():
    cfg = GentlenessConfig()
    # lambda = lambda' = [2, 2] (eq. 3 and 8 as the paper's Fig. 4 runs use them); no tolerance,
    # no curiosity normaliser, no multiplier: Method III is opt-in.
    assert (cfg.lam, cfg.lam_prime) == ((2.0, 2.0), (2.0, 2.0))
    assert cfg.tolerance is None and not cfg.curiosity_norm and cfg.multiplier == "none"
    check_group(cfg, "gentleness")  # valid as it stands


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"lam": (0.0, 2.0)}, r"gentleness.lam=\(0.0, 2.0\) must be \[lambda_1 > 0"),
        ({"lam_prime": (2.0, -1.0)}, r"gentleness.lam_prime=\(2.0, -1.0\) must be"),
        ({"multiplier": "pid"}, "steers toward the tolerance: set gentleness.tolerance"),
        ({"tolerance": 0.0}, "gentleness.tolerance=0.0"),
        ({"multiplier": "dual"}, "gentleness.multiplier='dual' is not one of"),
    ],
)
def test_a_group_built_in_python_is_refused_in_one_line_naming_the_field(change, message):
    with pytest.raises(ValueError, match=message) as err:
        check_group(GentlenessConfig(**change), "gentleness")
    assert "\n" not in str(err.value)


def test_a_tolerance_past_its_bound_would_zero_the_penalty_and_is_refused():
    """The penalty reads impacts in units of tolerance / lambda_2 (float32): at 1e300 the unit is
    inf in float32 and a 9 N impact costs 0; at the bound a 1 mN impact still costs a normal
    float32 penalty, and past it the tolerance is refused."""
    import torch

    from gentlerl.config.limits import MAX_FORCE
    from gentlerl.functional import impact_penalty, tolerance_unit

    def cost(impact, tolerance):
        return impact_penalty(torch.tensor([impact]) / tolerance_unit(tolerance)).item()

    assert cost(9.0, 1e300) == 0.0  # what the bound prevents
    assert cost(1e-3, MAX_FORCE) < -torch.finfo(torch.float32).tiny
    assert cost(MAX_FORCE, MAX_FORCE) == pytest.approx(-1.0)
    check_group(GentlenessConfig(tolerance=MAX_FORCE), "gentleness")
    check_group(GentlenessConfig(tolerance=1e-6), "gentleness")
    # the finding: tolerance=1e-300 passed and was blamed on the force unit
    for past in (MAX_FORCE * 1.001, 1e300, 1e-300, 9e-7):
        with pytest.raises(
            ValueError, match=r"gentleness.tolerance=\S+ must be in \[1e-06, 1000000.0\]"
        ):
            check_group(GentlenessConfig(tolerance=past), "gentleness")


@pytest.mark.parametrize(
    ("field", "at_bound", "past"),
    [
        ("multiplier_gains", (1e3, 1e3, 1e3), (1.0, 1e300, 0.0)),
        ("multiplier_integral_max", 1e6, 1e300),
        ("multiplier_base", 1e6, 1e300),
        ("multiplier_period", 10**10, 10**300),
        ("surprise_scale", 1e6, 1e300),
        ("dynamics_surprise_scale", 1e6, 1e300),
        ("icm_eta", 1e6, 1e300),
    ],
)
def test_method3_weights_and_scales_have_upper_bounds(field, at_bound, past):
    steered = {"tolerance": 2.0, "multiplier": "pid"}
    check_group(GentlenessConfig(**steered, **{field: at_bound}), "gentleness")
    with pytest.raises(ValueError, match=f"gentleness.{field}=.* must be"):
        check_group(GentlenessConfig(**steered, **{field: past}), "gentleness")
