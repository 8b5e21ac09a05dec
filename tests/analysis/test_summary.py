"""Runs read from the training loop's layout and their summary (synthetic logs, known numbers)."""

import numpy as np
import pytest
import yaml

from gentlerl.analysis.runs import (
    after_intrinsic_start,
    final_eval_episodes,
    final_policy_episodes,
    find_runs,
    intrinsic_start,
    load_run,
    seed_band,
    successful_final_impacts,
)
from gentlerl.analysis.summary import fade_ratio, format_table, summary_table, time_to_gentle
from gentlerl.apps.plot import main

EPISODES_HEADER = "frames,episode,success,broken,max_impact,return\n"


def _fake_run(root, variant, seed, lam2, success, impacts, **config):
    run = root / f"{variant}-{lam2}" / f"seed{seed}"
    scalars = run / "logs" / "scalars"
    (scalars / "eval").mkdir(parents=True)
    (scalars / "episode").mkdir()
    (scalars / "train").mkdir()
    config = dict(task="touch", variant=variant, seed=seed, lam_prime=[2.0, lam2], **config)
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    (scalars / "eval" / "success_rate.csv").write_text(
        "".join(f"{f},{s}\n" for f, s in zip((1000, 2000, 3000), success, strict=True))
    )
    (scalars / "eval" / "return.csv").write_text("1000,0\n2000,0.5\n3000,1\n")
    (scalars / "episode" / "max_impact.csv").write_text(
        "".join(f"{200 * (i + 1)},{m}\n" for i, m in enumerate(impacts))
    )
    (scalars / "train" / "batch_reward.csv").write_text("1000,0.0\n2000,0.1\n")
    (scalars / "train" / "intrinsic_on.csv").write_text("1000,0\n1500,1\n2000,1\n")
    return run


def test_summary_reports_the_fig3_and_fig5_selections(tmp_path):
    # Rollouts are logged at 200, 400, ..., 2000 frames; the intrinsic rewards switch on at 1500.
    run0 = _fake_run(tmp_path, "rs", 0, 2.0, (0.0, 1.0, 0.5), [9.0] * 7 + [0.0, 4.0, 6.0])
    run1 = _fake_run(tmp_path, "rs", 1, 2.0, (0.0, 0.0, 0.9), [9.0] * 7 + [12.0, 2.0, 0.0])
    (run0 / "logs/scalars/episode/broken.csv").write_text("200,1\n1600,0\n1800,1\n2000,0\n")
    # seed 0: only its last in-loop evaluation; seed 1: the evaluate episodes win over it.
    (run0 / "eval_episodes.csv").write_text(EPISODES_HEADER + "3000,0,1,0,1.5,1\n3000,1,0,1,4,0\n")
    (run1 / "eval_episodes.csv").write_text(EPISODES_HEADER + "3000,0,1,0,9.0,1\n")
    (run1 / "final_eval_episodes.csv").write_text(
        EPISODES_HEADER + "3000,0,1,0,2.5,1\n3000,1,1,0,3.5,1\n3000,2,0,0,0,0\n3000,3,1,0,5.5,1\n"
    )
    (row,) = summary_table(find_runs([tmp_path]))
    assert row["final_success"] == pytest.approx((0.5 + 0.75) / 2)
    assert row["final_source"] == "mixed" and row["final_episodes"] == 6
    assert row["final_successful"] == 4  # 1.5 | 2.5, 3.5, 5.5
    assert row["final_successful_median_impact"] == pytest.approx(3.0)
    assert row["mean_eval_success"] == pytest.approx((0.5 + 0.3) / 2)
    assert row["seeds_reaching_0.8"] == 2 and row["first_0.8_frames"] == pytest.approx(2500)
    # After the switch: 0, 4, 6 | 12, 2, 0; the 9 N rollouts before it are left out.
    assert row["switch_frames"] == 1500 and row["rollouts_after_switch"] == 6
    assert row["touching_share_after_switch"] == pytest.approx(4 / 6)
    assert row["median_impact_after_switch"] == pytest.approx(5.0)
    assert row["share_under_5N_after_switch"] == pytest.approx(0.5)
    assert row["share_5_15N_after_switch"] == pytest.approx(0.5)
    assert row["broken_share_after_switch"] == pytest.approx(1 / 3)
    assert format_table([row]).splitlines()[2].startswith("| touch | rs | 2 | 0.62 | mixed | 6 |")


def test_time_to_gentle_is_the_first_evaluation_that_succeeds_softly(tmp_path):
    run0 = _fake_run(tmp_path, "r+rf+rsp", 0, 2.0, (0.0, 1.0, 1.0), [1.0])
    run1 = _fake_run(tmp_path, "r+rf+rsp", 1, 2.0, (0.0, 0.0, 1.0), [1.0])
    # 1000: fails; 2000: succeeds at a median 4 N (too hard); 3000: 0.8 at a median 2.5 N.
    run0.joinpath("eval_episodes.csv").write_text(
        EPISODES_HEADER
        + "".join(f"1000,{i},0,0,0,0\n" for i in range(5))
        + "".join(f"2000,{i},1,0,{m},1\n" for i, m in enumerate((3, 4, 5, 4, 4)))
        + "".join(f"3000,{i},{int(i < 4)},0,{m},1\n" for i, m in enumerate((2, 2.5, 3.5, 9, 1)))
    )
    run0.joinpath("logs/scalars/train/wall_s.csv").write_text("1000,10\n2000,30\n4000,70\n")
    # seed 1 logged no wall clock and, with its force in 0.5 N units, 5 units is 2.5 N.
    run1.joinpath("config.yaml").write_text(
        yaml.safe_dump(
            {
                **yaml.safe_load(run1.joinpath("config.yaml").read_text()),
                "env": {"force_scale": 2.0},
            }
        )  # fmt: skip
    )
    run1.joinpath("eval_episodes.csv").write_text(EPISODES_HEADER + "2000,0,1,0,5,1\n")
    assert time_to_gentle(load_run(run0)) == (3000.0, 50.0)  # 30 + (70 - 30) / 2
    frames, seconds = time_to_gentle(load_run(run1))
    assert frames == 2000.0 and np.isnan(seconds)
    assert time_to_gentle(load_run(run0), impact_n=5.0) == (2000.0, 30.0)
    assert all(np.isnan(time_to_gentle(load_run(run0), success=1.1)))
    # Held: at 5 N, 2000 and 3000 are gentle -> 2000; at 3 N only the last -> 3000.
    assert time_to_gentle(load_run(run0), impact_n=5.0, held=True) == (2000.0, 30.0)
    assert time_to_gentle(load_run(run0), held=True) == (3000.0, 50.0)
    (row,) = summary_table(find_runs([tmp_path]))
    assert row["seeds_gentle"] == 2 and row["gentle_frames"] == pytest.approx(2500)
    assert row["gentle_wall_s"] == pytest.approx(50.0)  # the one seed with a wall clock
    assert row["seeds_held_gentle"] == 2 and row["held_gentle_frames"] == pytest.approx(2500)


def test_time_to_gentle_held_skips_a_lucky_first_evaluation(tmp_path):
    run = _fake_run(tmp_path, "r+rf+rsp", 0, 2.0, (0.0, 1.0, 1.0), [1.0])
    # gentle at 1000 (the untrained actor), not at 2000, gentle again at 3000 and 4000.
    run.joinpath("eval_episodes.csv").write_text(
        EPISODES_HEADER + "1000,0,1,0,2,1\n2000,0,0,0,0,0\n3000,0,1,0,2.5,1\n4000,0,1,0,1,1\n"
    )
    assert time_to_gentle(load_run(run))[0] == 1000.0
    assert time_to_gentle(load_run(run), held=True)[0] == 3000.0
    run.joinpath("eval_episodes.csv").write_text(
        EPISODES_HEADER + "1000,0,1,0,2,1\n2000,0,0,0,0,0\n"
    )
    assert np.isnan(time_to_gentle(load_run(run), held=True)[0])


def test_fade_ratio_compares_the_last_window_with_the_first_after_the_switch(tmp_path):
    run = _fake_run(tmp_path, "rf+rsp", 0, 2.0, (0.0, 0.0, 0.0), [1.0])  # switch at 1500
    path = run / "logs/scalars/train/penalty_surprise_per_contact_step.csv"
    # Before the switch 0; the first 1000 frames after it 2.0 and 4.0, the last 1000: 1.0, 2.0.
    path.write_text("1000,0\n1600,2\n2600,4\n3000,9\n4000,1\n4600,2\n")
    assert fade_ratio(load_run(run), window=1000) == pytest.approx(1.5 / 3.0)
    assert fade_ratio(load_run(run), window=10**6) == pytest.approx(1.0)  # one window: all
    assert np.isnan(fade_ratio(load_run(run), name="train/none"))
    (row,) = summary_table(find_runs([tmp_path]))
    assert row["rsp_fade"] == pytest.approx(1.0)  # the default 5k window holds the whole run


def test_a_variant_without_data_reads_nan_not_zero(tmp_path):
    _fake_run(tmp_path, "r", 0, 2.0, (0.0, 0.0, 0.0), [1.0])  # one rollout, before the switch
    (row,) = summary_table(find_runs([tmp_path]))
    assert row["final_source"] == "none" and row["final_episodes"] == 0
    for name in ("final_success", "final_successful_median_impact", "median_impact_after_switch"):
        assert np.isnan(row[name]), name
    assert row["rollouts_after_switch"] == 0 and np.isnan(row["touching_share_after_switch"])
    assert row["seeds_gentle"] == 0 and np.isnan(row["gentle_frames"])
    assert np.isnan(row["rsp_fade"])


def test_seed_band_interpolates_on_a_common_grid():
    a = (np.array([0.0, 10.0]), np.array([0.0, 1.0]))
    b = (np.array([0.0, 10.0]), np.array([1.0, 1.0]))
    grid, mean, low, high = seed_band([a, b], points=3)
    assert grid.tolist() == [0.0, 5.0, 10.0]
    assert mean.tolist() == [0.5, 0.75, 1.0]
    assert low.tolist() == [0.0, 0.5, 1.0] and high.tolist() == [1.0, 1.0, 1.0]


def test_cli_writes_the_three_figures_and_a_summary(tmp_path):
    _fake_run(tmp_path / "runs", "r+rf+rsp", 0, 3.0, (0.0, 0.5, 1.0), [1.0, 4.0])
    out = tmp_path / "figs"
    main([str(tmp_path / "runs"), "-o", str(out)])
    for name in ("impact_histograms.png", "learning_curves.png", "reward_components.png"):
        assert (out / name).stat().st_size > 5_000  # a real image, not an empty canvas
    assert "r+rf+rsp" in (out / "summary.csv").read_text()
    assert (out / "final_impacts.png").stat().st_size > 5_000
    assert "| touch | r+rf+rsp (λ'₂=3) | 1 |" in (out / "summary.md").read_text()


def test_missing_runs_are_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="no run directories"):
        find_runs([tmp_path])
    with pytest.raises(FileNotFoundError, match="no such run directory"):
        find_runs([tmp_path / "nope"])


def test_fig3_selection_starts_where_the_intrinsic_rewards_switch_on(tmp_path):
    # intrinsic_on first reads 1 at frame 1500: rollouts logged at 1600 and 1800 are kept.
    impacts = [9.0] * 7 + [0.0, 4.0, 2.0]  # logged at 200, 400, ..., 2000
    _fake_run(tmp_path, "rs", 0, 2.0, (0.0, 0.0, 0.0), impacts)
    (run,) = find_runs([tmp_path])
    assert intrinsic_start(run) == 1500.0
    assert after_intrinsic_start([run]).tolist() == [4.0, 2.0]
    assert after_intrinsic_start([run], with_zeros=True).tolist() == [0.0, 4.0, 2.0]


FLAT = dict(init_random_frames=1000, reward_delay=100, utd_ratio=0.25)  # earlier config.yaml
NESTED = dict(
    collector={"init_random_frames": 1000},
    gentleness={"reward_delay": 100},
    learner={"utd_ratio": 0.25},
)


@pytest.mark.parametrize("config", [FLAT, NESTED], ids=["flat", "nested"])
def test_fig3_selection_without_intrinsic_rewards_uses_the_same_frame(tmp_path, config):
    run = _fake_run(tmp_path, "r", 0, 2.0, (0.0, 0.0, 0.0), [1.0] * 10, **config)
    (run / "logs" / "scalars" / "train" / "intrinsic_on.csv").write_text("1000,0\n2000,0\n")
    (loaded,) = find_runs([tmp_path])
    assert intrinsic_start(loaded) == 1000 + 100 / 0.25
    assert len(after_intrinsic_start([loaded])) == 3  # logged at 1600, 1800, 2000


def test_fig3_selection_reads_the_grouped_config_of_current_runs(tmp_path):
    run = _fake_run(tmp_path, "r", 0, 2.0, (0.0, 0.0, 0.0), [1.0] * 10)
    config = yaml.safe_load((run / "config.yaml").read_text())
    config.update(
        collector={"init_random_frames": 1000},
        gentleness={"reward_delay": 100, "lam_prime": [2.0, 2.0]},
        learner={"utd_ratio": 0.25},
    )
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    (run / "logs" / "scalars" / "train" / "intrinsic_on.csv").write_text("1000,0\n2000,0\n")
    assert intrinsic_start(load_run(run)) == 1000 + 100 / 0.25


def test_fig5_selection_is_the_successful_rollouts_of_the_last_evaluation(tmp_path):
    run = _fake_run(tmp_path, "r", 0, 2.0, (0.0, 0.0, 0.0), [1.0])
    (run / "eval_episodes.csv").write_text(
        "frames,episode,success,broken,max_impact,return\n"
        "1000,0,1,0,9.0,1\n1000,1,0,0,8.0,0\n"  # an earlier evaluation: ignored
        "3000,0,1,0,1.5,1\n3000,1,0,1,4.0,-0.5\n3000,2,1,0,2.5,1\n"
    )
    other = _fake_run(tmp_path, "r", 1, 2.0, (0.0, 0.0, 0.0), [1.0])  # never evaluated
    runs = find_runs([tmp_path])
    assert final_eval_episodes(runs[0])["frames"].tolist() == [3000.0] * 3
    assert successful_final_impacts(runs).tolist() == [1.5, 2.5]
    assert len(final_eval_episodes(load_run(other))) == 0


def test_fig5_prefers_the_evaluate_episodes_unless_they_are_older_than_the_run(tmp_path):
    run = _fake_run(tmp_path, "r", 0, 2.0, (0.0, 0.0, 0.0), [1.0])
    (run / "eval_episodes.csv").write_text(EPISODES_HEADER + "3000,0,1,0,1.0,1\n")
    (run / "final_eval_episodes.csv").write_text(EPISODES_HEADER + "2000,0,1,0,7.0,1\n")
    rows, source = final_policy_episodes(load_run(run))  # evaluated an actor of 2000 frames
    assert source == "in-loop" and rows["max_impact"].tolist() == [1.0]
    (run / "final_eval_episodes.csv").write_text(EPISODES_HEADER + "3000,0,1,0,7.0,1\n")
    rows, source = final_policy_episodes(load_run(run))
    assert source == "evaluate" and successful_final_impacts([load_run(run)]).tolist() == [7.0]


def test_the_printed_table_leaves_out_columns_no_run_has_data_for():
    """An external env's runs have no success or broken rate: no ``nan`` column is printed."""
    nan = float("nan")
    rows = [
        {"task": "finger-spin", "final_success": nan, "final_return": 145.5},
        {"task": "finger-spin", "final_success": nan, "final_return": 0.0},
    ]
    table = format_table(rows)
    assert "final_success" not in table and "nan" not in table
    assert table.splitlines()[0] == "| task | final_return |"
    rows[1]["final_success"] = 0.5  # one run with data keeps the column, nan where it has none
    assert "| finger-spin | nan | 145.50 |" in format_table(rows)


def test_a_run_name_with_a_line_break_stays_one_markdown_cell():
    """The finding: a run folder named with a newline injected a row into summary.md."""
    from gentlerl.analysis.summary import format_table

    table = format_table([{"run": "evil\n| 1.00 | 0.0 |", "success": 0.5}])
    lines = table.splitlines()
    assert len(lines) == 3 and lines[2] == "| evil \\| 1.00 \\| 0.0 \\| | 0.50 |"
