"""A suite's results file (analysis.results): a run's final evaluation read from its run
directory, the file written whole and read back exactly, a damaged file refused in one line."""

import pytest

from gentlerl.analysis.results import RESULT_COLUMNS, read_results, run_result, write_results
from gentlerl.training import train
from tests.helpers import tiny_config, toy_env


def _row(**changes):
    row = dict(
        suite="s", cell="touch/r", task="touch", variant="r", seed=0, frames=300,
        success_rate=1.0, broken_rate=None, max_impact=2.0000000000000004, wall_s=1.5,
        grouped=1, version="0.2.0", commit="unknown", date="2026-12-06", cost=None,
    )  # fmt: skip
    row["return"] = 0.1 + 0.2  # 0.30000000000000004: written as repr, read back exactly
    return {**row, **changes}


def test_rows_are_written_whole_and_read_back_exactly(tmp_path):
    path = tmp_path / "results.csv"
    rows = [_row(), _row(seed=1, success_rate=None)]
    write_results(path, rows)
    assert path.read_text().splitlines()[0] == ",".join(RESULT_COLUMNS)
    assert read_results(path) == rows
    assert [p.name for p in tmp_path.iterdir()] == ["results.csv"]  # no temporary file left


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("max_impact,", ""), "no column max_impact"),
        (lambda t: t.replace(",300,", ",3OO,"), ":2: frames='3OO' is not a number"),
        (lambda t: t + t.splitlines()[1] + "\n", ":3: run touch/r seed 0 appears twice"),
        (lambda t: t + "s,touch/r,touch\n", ":3: expected 16 fields"),
    ],
)
def test_a_damaged_results_file_is_refused_naming_the_line(tmp_path, edit, message):
    path = tmp_path / "results.csv"
    write_results(path, [_row()])
    path.write_text(edit(path.read_text()))
    with pytest.raises(ValueError, match="results.csv") as refused:
        read_results(path)
    assert message in str(refused.value)


def test_the_cost_column_round_trips_and_an_older_file_without_it_reads_as_not_measured(tmp_path):
    path = tmp_path / "results.csv"
    rows = [_row(cost=12.5), _row(seed=1)]
    write_results(path, rows)
    assert read_results(path) == rows
    # a results file written before the column: the same rows, the cost not measured
    older = [line.rsplit(",", 1)[0] for line in path.read_text().splitlines()]
    assert older[0].endswith(",date")
    path.write_text("\n".join(older) + "\n")
    assert [row["cost"] for row in read_results(path)] == [None, None]
    assert read_results(path)[0]["return"] == rows[0]["return"]


def test_a_runs_result_is_its_final_evaluation(tmp_path):
    summary = train(tiny_config(tmp_path / "run", total_frames=300), toy_env)
    result = run_result(tmp_path / "run")
    assert result["frames"] == 300
    assert result["return"] == summary["return"]
    assert result["success_rate"] == summary["success_rate"]
    assert result["broken_rate"] == summary["broken_rate"]
    assert result["max_impact"] == pytest.approx(summary["max_impact_mean"], rel=1e-6)
    assert result["wall_s"] > 0
    with pytest.raises(ValueError, match="no evaluation episodes"):
        (tmp_path / "run" / "eval_episodes.csv").write_text("")
        run_result(tmp_path / "run")
