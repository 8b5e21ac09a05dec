"""Figures: evaluations drawn as points, panels only for distinct quantities, seed counts, CLI."""

from pathlib import Path

import numpy as np
import pytest

from gentlerl.figures import (
    build_parser,
    distinct_metrics,
    eval_points,
    learning_curves_figure,
    main,
    resolve_run_paths,
    seeds_label,
)
from gentlerl.plot import find_runs
from tests.test_plot import _fake_run


def _series(frames, values):
    return np.array(frames, dtype=float), np.array(values, dtype=float)


def test_eval_points_keep_every_evaluation_without_interpolating():
    # A run that logs 1.0 at 15k and 0.0 at 20k must show both (not ~0.94).
    seed0 = _series([5000, 10000, 15000, 20000], [0.0, 0.5, 1.0, 0.0])
    seed1 = _series([5000, 10000, 15000], [0.0, 1.0, 1.0])  # stopped before 20k
    frames, mean, low, high = eval_points([seed0, seed1])
    assert frames.tolist() == [5000, 10000, 15000, 20000]
    assert mean.tolist() == [0.0, 0.75, 1.0, 0.0]  # at 20k only seed 0 evaluated
    assert low.tolist() == [0.0, 0.5, 1.0, 0.0] and high.tolist() == [0.0, 1.0, 1.0, 0.0]
    assert all(len(a) == 0 for a in eval_points([]))


def test_learning_curve_line_passes_through_the_seed_means_at_the_evaluated_frames(tmp_path):
    _fake_run(tmp_path, "r", 0, 2.0, (0.0, 1.0, 0.0), [1.0])
    _fake_run(tmp_path, "r", 1, 2.0, (0.0, 0.5, 1.0), [1.0])
    fig = learning_curves_figure(find_runs([tmp_path]))
    ax = fig.axes[0]  # success rate (the fake return, 0 / 0.5 / 1, gets a second panel)
    assert len(fig.axes) == 2
    mean_line, *seed_points = ax.lines
    assert mean_line.get_xydata().tolist() == [[1000, 0.0], [2000, 0.75], [3000, 0.5]]
    assert mean_line.get_marker() == "o"
    assert sorted(p.get_ydata().tolist() for p in seed_points) == [[0.0, 0.5, 1.0], [0.0, 1.0, 0.0]]
    assert seed_points[0].get_linestyle() == "None"  # points, not a curve
    band = ax.collections[0].get_paths()[0].vertices
    assert band[:, 1].min() == 0.0 and band[:, 1].max() == 1.0  # min-max over seeds
    assert ax.get_legend().get_texts()[0].get_text() == "touch: r (2 seeds)"


def _fake_run_with_return(tmp_path, name, success, returns):
    run = _fake_run(tmp_path / name, "r", 0, 2.0, success, [1.0])
    values = "".join(f"{f},{v}\n" for f, v in zip((1000, 2000, 3000), returns, strict=True))
    (run / "logs" / "scalars" / "eval" / "return.csv").write_text(values)


def test_return_panel_only_where_it_differs_from_success(tmp_path):
    metrics = [("eval/success_rate", "success rate"), ("eval/return", "return")]
    _fake_run_with_return(tmp_path, "same", (0.0, 1.0, 0.5), (0.0, 1.0, 0.5))
    runs = find_runs([tmp_path / "same"])
    assert distinct_metrics(runs, metrics) == metrics[:1]
    assert len(learning_curves_figure(runs).axes) == 1
    assert learning_curves_figure(runs).axes[0].get_legend().get_texts()[0].get_text() == (
        "touch: r (1 seed)"
    )
    _fake_run_with_return(tmp_path, "fragile", (0.0, 1.0, 0.5), (-3.0, 1.0, 0.5))
    assert distinct_metrics(find_runs([tmp_path]), metrics) == metrics


def test_seed_counts_read_as_english():
    assert [seeds_label(n) for n in (1, 2, 3)] == ["1 seed", "2 seeds", "3 seeds"]


def test_a_sweep_file_stands_for_its_runs(tmp_path):
    sweep = tmp_path / "fig4_touch.yaml"
    sweep.write_text("method: grid\n")
    paths = resolve_run_paths([str(sweep), "runs/x"], tmp_path / "out")
    assert paths == [tmp_path / "out" / "fig4_touch", Path("runs/x")]
    _fake_run(tmp_path / "out" / "fig4_touch", "r", 0, 2.0, (0.0, 1.0, 1.0), [1.0])
    main([str(sweep), "--sweeps-out", str(tmp_path / "out"), "-o", str(tmp_path / "figs")])
    assert "| touch | r | 1 |" in (tmp_path / "figs" / "summary.md").read_text()
    assert not list((tmp_path / "figs").glob(".*.tmp"))  # written atomically


def test_plot_help_gives_every_option_a_default_and_a_help_text():
    parser = build_parser()
    for action in parser._actions:
        assert action.help, action.dest
    text = " ".join(parser.format_help().split())
    assert "(default: figures)" in text and "(default: runs/sweeps)" in text
    with pytest.raises(SystemExit):
        parser.parse_args([])  # at least one run folder
