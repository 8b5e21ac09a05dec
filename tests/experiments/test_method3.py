"""The Method III table (experiments/method3/table.py) and its pre-registered tests
(experiments/method3/criteria.py), on synthetic runs."""

import pytest
import yaml

from experiments.method3.criteria import method3_equal_impact, method3_verdicts
from experiments.method3.table import method3_table


def _row(score: float, impact: float, rsp: float = 1.0) -> dict[str, float]:
    return {"score": score, "median_score": score, "median_impact": impact, "rsp_per_contact": rsp}


@pytest.mark.parametrize(
    ("new", "baseline", "verdict"),
    [
        (_row(1.0, 2.0), _row(0.9, 2.0), "holds"),
        (_row(0.8, 2.4), _row(0.9, 2.0), "does not hold"),  # 1.2x the impact: equal enough
        (_row(1.0, 2.6), _row(0.9, 2.0), "not at equal impact"),  # 1.3x
    ],
)
def test_b_compares_scores_only_at_about_equal_impact(new, baseline, verdict):
    assert method3_equal_impact(new, baseline).startswith(verdict)


def test_the_tests_by_hand():
    rows = {
        "touch": {"new": _row(0.97, 2.9, rsp=1.0), "baseline": _row(0.5, 1.0)},
        "fragile": {"new": _row(0.7, 1.5)},
        "finger-turn_easy": {"r": _row(300.0, 40.0), "new": _row(250.0, 19.0, rsp=2.5)},
    }
    out = method3_verdicts(rows)
    assert out["H1 touch"].startswith("holds")
    assert out["H2 fragile"] == "does not hold (0.70)"
    assert out["F1 finger-turn_easy"].startswith("holds")  # 250 >= 240, 19 <= 20
    assert out["B touch"].startswith("not at equal impact")
    assert out["N finger-turn_easy"] == "does not hold (finger-turn_easy / touch = 2.50)"
    assert "B fragile" not in out  # no baseline row: no test


def test_the_fifth_amendments_candidate_gets_every_test_on_both_fingers():
    rows = {
        "touch": {"new, w0=1": _row(0.93, 2.63, rsp=1.3)},
        "finger-turn_easy": {
            "r": _row(300.0, 40.0),
            "new, w0=1": _row(240.0, 20.0, rsp=2.4),  # 0.8x at 0.5x: both at the threshold
            "baseline": _row(250.0, 18.0),  # 20 <= 1.25 x 18 = 22.5: equal enough, 240 < 250
        },
        "finger-spin": {"r": _row(145.5, 700.0), "new, w0=1": _row(116.0, 10.0, rsp=0.6)},
    }
    out = method3_verdicts(rows)
    assert out == {
        "H1 touch, new, w0=1": "does not hold (success 0.93 at 2.63 N)",
        "F1 finger-turn_easy, new, w0=1": (
            "holds (median return 240.0 vs r 300.0, 20.0 vs 40.0 N)"
        ),
        "F2 finger-spin, new, w0=1": (  # 116.0 < 0.8 x 145.5 = 116.4
            "does not hold (median return 116.0 vs r 145.5, 10.0 vs 700.0 N)"
        ),
        "B finger-turn_easy, new, w0=1": "does not hold (240.00 at 20.00 N vs 250.00 at 18.00 N)",
        "N finger-turn_easy, new, w0=1": "holds (finger-turn_easy / touch = 1.85)",
        "N finger-spin, new, w0=1": "does not hold (finger-spin / touch = 0.46)",
    }


def _run(root, name, config, episodes, rsp=None):
    run = root / name
    (run / "logs" / "scalars" / "train").mkdir(parents=True)
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    rows = ["frames,episode,success,broken,max_impact,return"]
    rows += [f"0,{i},{s},0,{m},{r}" for i, (s, m, r) in enumerate(episodes)]
    (run / "final_eval_episodes.csv").write_text("\n".join(rows) + "\n")
    if rsp is not None:
        csv = "\n".join(f"{f},{v}" for f, v in rsp) + "\n"
        (run / "logs" / "scalars" / "train" / "penalty_surprise_per_contact_step.csv").write_text(
            csv
        )


def test_the_table_labels_the_four_rows_and_prints_the_tests(tmp_path):
    for seed in range(2):
        base = {"task": "touch", "seed": seed, "env": {"name": None, "force_scale": 1.0}}
        plain = {**base, "gentleness": {"multiplier": "none"}}
        steered = {**base, "gentleness": {"multiplier": "pid", "curiosity_norm": True}}
        _run(tmp_path, f"r{seed}", {**plain, "variant": "r"}, [(1, 6.0, 1.0), (1, 8.0, 1.0)])
        _run(tmp_path, f"n{seed}", {**steered, "variant": "r+rf+rsp"},
             [(1, 2.0, 1.0), (seed, 3.0, 1.0)], rsp=[(0, 9.0), (20_000, 3.0), (30_000, 1.0)])  # fmt: skip
        _run(tmp_path, f"b{seed}", {**steered, "variant": "r+rf"}, [(0, 1.0, 0.0)] * 2)
    out = method3_table(tmp_path)
    assert "| touch | `r` | 1.00 ± 0.00 (1.00 / 1.00) | 7.00 ± 0.00, 8.00 | nan |" in out
    # success 0.5 and 1.0; impacts 2, 3 per seed: median 2.5 (std 0); r^sp over the last 10k
    # frames: (3 + 1) / 2 = 2
    assert "| touch | `new` | 0.75 ± 0.25 (0.50 / 1.00) | 2.50 ± 0.00, 3.00 | 2.00 |" in out
    assert "| touch | `baseline` | 0.00 ± 0.00 (0.00 / 0.00) |" in out
    assert "- **H1 touch**: does not hold (success 0.75 at 2.50 N)" in out
    assert "- **B touch**: not at equal impact" in out


def test_each_mechanism_alone_gets_its_own_row_and_hand_tests():
    from experiments.method3.table import method3_label
    from gentlerl.analysis.runs import Run

    def label(variant, **gentleness):
        return method3_label(Run(path=None, config={"variant": variant, "gentleness": gentleness}))

    assert label("r+rf+rsp", multiplier="pid", curiosity_norm=True) == "new"
    assert label("r+rf+rsp", multiplier="pid") == "pid alone"
    # the fourth amendment's new method: the multiplier on the deployed policy's episodes
    deployed = dict(multiplier="pid", multiplier_episodes=3)
    assert label("r+rf+rsp", multiplier_base=0.0, **deployed) == "new"
    assert label("r+rf+rsp", **deployed) == "new, w0=1"  # the paper's weight as its floor
    assert label("r+rf+rsp", curiosity_norm=True) == "norm alone"
    assert label("r+rf+rsp") == "r+rf+rsp" and label("r+rf", multiplier="pid") == "baseline"
    row = {"score": 1.0, "median_impact": 2.5}
    verdicts = method3_verdicts({"touch": {"pid alone": row}, "fragile": {"norm alone": row}})
    assert verdicts == {
        "H1 touch, pid alone": "holds (success 1.00 at 2.50 N)",
        "H2 fragile, norm alone": "holds (1.00)",
    }


def test_runs_that_differ_in_method_iiis_switches_are_not_pooled():
    from gentlerl.analysis.runs import Run

    paper = Run(path=None, config={"variant": "r+rf+rsp", "gentleness": {"lam_prime": [2, 2]}})
    steered = {"lam_prime": [2, 2], "curiosity_norm": True, "multiplier": "pid"}
    new = Run(path=None, config={"variant": "r+rf+rsp", "gentleness": steered})
    baseline = Run(path=None, config={"variant": "r+rf", "gentleness": steered})
    assert paper.label == "r+rf+rsp (λ'₂=2)"
    assert new.label == "r+rf+rsp (λ'₂=2) + norm + pid"
    assert baseline.label == "r+rf + pid"
    deployed = {"lam_prime": [2, 2], "multiplier": "pid", "multiplier_episodes": 3}
    floor = Run(path=None, config={"variant": "r+rf+rsp", "gentleness": deployed})
    lagrangian = Run(
        path=None, config={"variant": "r+rf+rsp", "gentleness": {**deployed, "multiplier_base": 0}}
    )
    assert floor.label == "r+rf+rsp (λ'₂=2) + pid on the deployed policy"
    assert lagrangian.label == "r+rf+rsp (λ'₂=2) + pid on the deployed policy, w0=0"
