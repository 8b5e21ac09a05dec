"""The SAC grid's and GentleBench's pre-registered verdicts (analysis.criteria) and their tables
(analysis.grid_tables, ``gentlerl table``) from synthetic runs with known numbers."""

import json
import math

import pytest
import yaml

from gentlerl import cli
from gentlerl.analysis.criteria import GENTLEBENCH_R_LEARNS, gentlebench_verdict, sac_verdict


def _sac(success: float, impact: float) -> dict[str, float]:
    return {"mean_success": success, "successful_impact": impact}


@pytest.mark.parametrize(
    ("task", "r", "rsp", "verdict"),
    [
        ("touch", _sac(1.0, 6.0), _sac(0.9, 4.0), "gentleness transfers"),
        ("touch", _sac(1.0, 6.0), _sac(0.5, 4.0), "gentler but less successful"),
        ("touch", _sac(1.0, 6.0), _sac(1.0, 5.0), "not gentler"),  # 5 > 0.75 x 6
        ("touch", _sac(1.0, 6.0), _sac(1.0, 4.5), "gentleness transfers"),  # 4.5 = 0.75 x 6
        ("fragile", _sac(0.3, 6.0), _sac(0.4, 1.0), "SAC does not learn the task at this budget"),
        ("fragile", _sac(0.3, 6.0), _sac(0.9, 2.0), "gentleness transfers; helps on the fragile block"),
        ("touch", _sac(0.3, 6.0), _sac(0.9, 2.0), "gentleness transfers"),  # touch: no fragile note
        (
            "touch", _sac(0.0, math.nan), _sac(1.0, 2.5),
            "more successful than r, which never succeeds; impacts not comparable",
        ),
        (
            "touch", _sac(0.6, math.nan), _sac(0.4, math.nan),
            "neither variant succeeds often enough to compare impacts",
        ),
    ],
)  # fmt: skip
def test_sac_verdict_applies_docs_sac_rule(task, r, rsp, verdict):
    assert sac_verdict(task, r, rsp) == verdict


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


def _sac_run(root, task, variant, seed, success, successful_impact):
    run = root / task / variant / f"seed{seed}"
    run.mkdir(parents=True)
    row = {
        "success_rate": success, "broken_rate": 0.0, "median_max_impact": 3.0,
        "p90_max_impact": 7.0, "median_max_impact_successful": successful_impact,
    }  # fmt: skip
    (run / "final_eval.json").write_text(json.dumps(row))


def test_the_sac_table_prints_each_row_and_the_verdict_of_each_task(tmp_path, capsys):
    for seed, (s_r, s_rsp) in enumerate([(1.0, 0.9), (0.8, 1.0), (0.9, 0.9)]):
        _sac_run(tmp_path, "touch", "r", seed, s_r, 6.0 + seed)
        _sac_run(tmp_path, "touch", "r+rf+rsp", seed, s_rsp, 3.0 + seed)
    assert cli.main(["table", "sac", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| touch | `r` | 3 | 1.00 / 0.80 / 0.90 | 0.90 | 0.00 | 3.00 / 7.00 | 7.00 |" in out
    assert "| touch | `r+rf+rsp` | 3 | 0.90 / 1.00 / 0.90 | 0.93 |" in out
    assert out.rstrip().endswith("touch: gentleness transfers")  # 4 <= 0.75 x 7, 0.93 >= 0.72
    for seed in range(3):  # Method III's row: judged against r by the same rule
        _sac_run(tmp_path, "touch", "new", seed, 0.4, 2.0)
    assert cli.main(["table", "sac", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "touch: gentleness transfers" in out
    assert out.rstrip().endswith("touch, new: gentler but less successful")  # 0.4 < 0.72
    for seed in range(3):  # the fifth amendment's candidate (w = 1 + mu), judged alike
        _sac_run(tmp_path, "touch", "new_w1", seed, 0.9, 2.0)
    assert cli.main(["table", "sac", str(tmp_path)]) == 0
    assert capsys.readouterr().out.rstrip().endswith("touch, new_w1: gentleness transfers")


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


def test_the_gentlebench_table_undoes_the_force_scale_and_judges_against_r(tmp_path, capsys):
    for seed in range(3):
        _bench_run(tmp_path, "finger_spin", "r", seed, [100.0, 100.0], [10.0, 10.0])
        _bench_run(tmp_path, "finger_spin", "r+rf+rsp", seed, [90.0, 90.0], [4.0, 0.0])
    assert cli.main(["table", "gentlebench", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| finger_spin | `r` | 100.0 / 100.0 / 100.0 | 100.0 | 10.0 / 10.0 | 100% |  |" in out
    assert (
        "| finger_spin | `r+rf+rsp` | 90.0 / 90.0 / 90.0 | 90.0 | 2.0 / 4.0 | 50% | "
        "gentle and as good |"
    ) in out


def test_the_table_command_refuses_a_folder_without_runs_in_one_line(tmp_path, capsys):
    assert cli.main(["table", "sac", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no <task>/<variant>/seed<k>/final_eval.json under" in err
    assert cli.main(["table", "gentlebench", str(tmp_path / "nowhere")]) == 1
    assert "nowhere: no such directory" in capsys.readouterr().err
