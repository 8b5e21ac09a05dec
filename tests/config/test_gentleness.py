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
