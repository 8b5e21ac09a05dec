"""GentleBench's pre-registered verdict (experiments/gentlebench/criteria.py) and its table
(experiments/gentlebench/table.py) from synthetic runs with known numbers."""

import pytest
import yaml

from experiments.gentlebench.criteria import GENTLEBENCH_R_LEARNS, gentlebench_verdict
from experiments.gentlebench.table import gentlebench_table


def _bench(ret: float, impact: float) -> dict[str, float]:
    return {"median_return": ret, "median_impact": impact}


@pytest.mark.parametrize(
    ("other", "verdict"),
    [
        (_bench(80.0, 5.0), "gentle and as good"),  # 80 = 0.8 x 100, 5 = 0.5 x 10
        (_bench(79.0, 5.0), "gentle but worse"),
        (_bench(90.0, 6.0), "no gentleness gain"),
        (_bench(10.0, 9.0), "neither"),
    ],
)
def test_gentlebench_verdict_applies_the_two_tests_against_r(other, verdict):
    assert gentlebench_verdict(_bench(100.0, 10.0), other) == verdict


def test_gentlebench_does_not_judge_a_task_r_does_not_learn():
    r = _bench(GENTLEBENCH_R_LEARNS - 0.1, 10.0)
    assert (
        gentlebench_verdict(r, _bench(500.0, 1.0)) == "not judged: r does not learn at 30k; gentler"
    )
    assert gentlebench_verdict(r, _bench(500.0, 9.0)) == "not judged: r does not learn at 30k"


def _bench_run(root, task, variant, seed, returns, impacts, scale=2.0):
    run = root / f"gentlebench_{task}" / f"variant-{variant}_seed-{seed}"
    run.mkdir(parents=True)
    config = {
        "seed": seed, "variant": variant,
        "env": {"name": f"dm_control:{task}", "force_scale": scale},
    }  # fmt: skip
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    rows = ["frames,episode,success,broken,max_impact,return"]
    rows += [
        f"0,{i},0,0,{m * scale},{r}" for i, (r, m) in enumerate(zip(returns, impacts, strict=True))
    ]
    (run / "final_eval_episodes.csv").write_text("\n".join(rows) + "\n")


def test_the_gentlebench_table_undoes_the_force_scale_and_judges_against_r(tmp_path):
    for seed in range(3):
        _bench_run(tmp_path, "finger_spin", "r", seed, [100.0, 100.0], [10.0, 10.0])
        _bench_run(tmp_path, "finger_spin", "r+rf+rsp", seed, [90.0, 90.0], [4.0, 0.0])
    out = gentlebench_table(tmp_path)
    assert "| finger_spin | `r` | 100.0 / 100.0 / 100.0 | 100.0 | 10.0 / 10.0 | 100% |  |" in out
    assert (
        "| finger_spin | `r+rf+rsp` | 90.0 / 90.0 / 90.0 | 90.0 | 2.0 / 4.0 | 50% | "
        "gentle and as good |"
    ) in out


def test_the_script_refuses_a_missing_folder_in_one_line(tmp_path, capsys):
    from experiments.gentlebench import table

    with pytest.raises(SystemExit) as stop:
        table.main(table.gentlebench_table, "t", "table.py", [str(tmp_path / "nowhere")])
    assert str(stop.value.code).endswith("nowhere: no such directory")
    with pytest.raises(SystemExit, match="no gentlebench_<task>/<run>/final_eval_episodes.csv"):
        table.main(table.gentlebench_table, "t", "table.py", [str(tmp_path)])
