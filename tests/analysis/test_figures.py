"""Figures: evaluations drawn as points, panels only for distinct quantities, seed counts, CLI."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from gentlerl.analysis.curves import (
    distinct_metrics,
    eval_points,
    learning_curve_panels,
    learning_curves_figure,
    seeds_label,
)
from gentlerl.analysis.runs import (
    final_impacts,
    find_runs,
    group_runs,
    judged_by_success,
    successful_final_impacts,
)
from gentlerl.apps.plot import build_parser, main, resolve_run_paths
from tests.analysis.test_summary import EPISODES_HEADER, _fake_run


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


def test_learning_curves_are_points_with_min_max_bars_not_lines(tmp_path):
    _fake_run(tmp_path, "r", 0, 2.0, (0.0, 1.0, 0.0), [1.0])
    _fake_run(tmp_path, "r", 1, 2.0, (0.0, 0.5, 1.0), [1.0])
    fig = learning_curves_figure(find_runs([tmp_path]))
    assert len(fig.axes) == 2  # success rate, and the fake return (0 / 0.5 / 1) that differs
    (bars,) = fig.axes[0].containers
    points = bars.lines[0]
    assert points.get_xydata().tolist() == [[1000, 0.0], [2000, 0.75], [3000, 0.5]]
    assert points.get_linestyle() == "None" and points.get_marker() == "o"  # nothing between
    segments = [s.tolist() for s in bars.lines[2][0].get_segments()]  # min-max over seeds
    assert segments == [[[1000, 0.0], [1000, 0.0]], [[2000, 0.5], [2000, 1.0]],
                        [[3000, 0.0], [3000, 1.0]]]  # fmt: skip
    legend = fig.axes[1].get_legend()  # under the bottom panel, outside the data
    assert legend.get_texts()[0].get_text() == "r (2 seeds)"
    assert legend.get_bbox_to_anchor().y0 < fig.axes[1].get_window_extent().y0


def _grid(root, task, variants, lams):
    for variant in variants:
        for lam2 in lams if "rsp" in variant else (2.0,):
            run = _fake_run(root / task, variant, 0, lam2, (0.0, 1.0, 1.0), [1.0])
            config = yaml.safe_load((run / "config.yaml").read_text())
            (run / "config.yaml").write_text(yaml.safe_dump({**config, "task": task}))


def _bands(ax):
    """The variants in a panel's legend (without the seed count)."""
    return [t.get_text().rsplit(" (", 1)[0] for t in ax.get_legend().get_texts()]


REWARD_VARIANTS = ("r", "r+rf", "r+rf+rs", "r+icm", "r+rf+rsp")


def test_one_panel_per_claim_with_at_most_four_bands(tmp_path):
    _grid(tmp_path, "touch", REWARD_VARIANTS, (1.5, 2.0, 3.0))
    _grid(tmp_path, "fragile", REWARD_VARIANTS, (1.0, 1.5, 2.0))
    _grid(tmp_path, "explore", ("rs", "rf+rs", "rf+rsp"), (2.0, 3.0, 4.0))
    runs = find_runs([tmp_path])
    titles = [title for title, _ in learning_curve_panels(group_runs(runs))]
    assert titles == [
        "explore: variants", "explore: variants",  # no claim compares these: 5 in 3 + 2
        "fragile: claim 4: the penalty alone",
        "fragile: claim 5: penalty surprise vs task only",
        "fragile: claim 6: curiosity baselines",
        "touch: claim 4: the penalty alone",
        "touch: claim 5: penalty surprise vs task only",
        "touch: claim 6: curiosity baselines",
    ]  # fmt: skip
    fig = learning_curves_figure(runs)
    assert len(fig.axes) == 8 * 2  # success and (fake) return per panel
    bands = [_bands(ax) for ax in fig.axes[8:]]  # the bottom row carries the legends
    assert [len(b) for b in bands] == [3, 2, 3, 4, 3, 3, 4, 3]
    assert bands[5] == ["r", "r+rf", "r+rf+rs"]
    rsp = "r+rf+rsp (λ'₂={})".format
    assert bands[6] == ["r", rsp("1.5"), rsp(2), rsp(3)]
    assert bands[7] == ["r", "r+icm", rsp(2)]  # claim 6 at the primary lambda'_2 of touch
    assert bands[4] == ["r", "r+icm", rsp("1.5")]  # and of fragile
    assert all(len(ax.containers) == len(b) for ax, b in zip(fig.axes[8:], bands, strict=True))


def test_a_claim_with_more_lambdas_than_bands_is_split(tmp_path):
    _grid(tmp_path, "touch", ("r", "r+rf+rsp"), (1.0, 1.5, 2.0, 3.0, 4.0))
    panels = learning_curve_panels(group_runs(find_runs([tmp_path])))
    assert [len(keys) for _, keys in panels] == [4, 3]  # r repeated in both
    assert all(keys[0] == ("touch", "r") for _, keys in panels)
    assert len({title for title, _ in panels}) == 1  # claim 6 (r, rsp at 2) is already shown


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
        "r (1 seed)"
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


def _external_run(root, variant, seed, returns, impacts):
    """A run on an env without a success outcome (success logged as NaN), as finger-spin's."""
    run = _fake_run(root, variant, seed, 2.0, (np.nan,) * 3, [1.0], env={"name": "ext:spin"})
    values = "".join(f"{f},{v}\n" for f, v in zip((1000, 2000, 3000), returns, strict=True))
    (run / "logs" / "scalars" / "eval" / "return.csv").write_text(values)
    rows = "".join(f"3000,{i},nan,nan,{m},{returns[-1]}\n" for i, m in enumerate(impacts))
    (run / "final_eval_episodes.csv").write_text(EPISODES_HEADER + rows)
    return run


def test_an_env_without_success_is_drawn_by_its_return_and_every_final_rollout(tmp_path):
    _external_run(tmp_path, "r", 0, (0.0, 50.0, 140.0), [600.0, 700.0])
    _external_run(tmp_path, "r+rf", 0, (0.0, 0.0, 0.0), [0.0, 0.0])
    runs = find_runs([tmp_path])
    fig = learning_curves_figure(runs)
    assert len(fig.axes) == 1  # no empty success-rate row: the return only
    assert fig.axes[0].get_ylabel() == "eval return"
    # the paper's contrast, named without the paper's claim (about the hand tasks)
    assert fig.axes[0].get_title() == "ext:spin: the penalty alone"
    main([str(tmp_path), "-o", str(tmp_path / "figs")])
    assert judged_by_success(runs) is False
    assert sorted(final_impacts([r for r in runs if r.variant == "r"])) == [600.0, 700.0]
    assert len(successful_final_impacts(runs)) == 0  # the selection the hand's Fig. 5 uses


def test_final_impacts_are_chosen_per_panel_when_hand_and_external_runs_mix(tmp_path, monkeypatch):
    from gentlerl.analysis import figures

    hand = _fake_run(tmp_path / "hand", "r", 0, 2.0, (0.0, 1.0, 1.0), [1.0])
    rows = "3000,0,1,0,2.5,1\n3000,1,0,1,9.0,0\n"  # one success at 2.5 N, one break at 9 N
    (hand / "final_eval_episodes.csv").write_text(EPISODES_HEADER + rows)
    _external_run(tmp_path / "ext", "r", 0, (0.0, 50.0, 140.0), [600.0, 700.0])
    drawn = {}
    monkeypatch.setattr(figures, "_save", lambda fig, path: drawn.setdefault("fig", fig))
    figures.plot_final_impacts(find_runs([tmp_path]), tmp_path)
    legends = {
        ax.get_title(): ax.get_legend().get_texts()[0].get_text() for ax in drawn["fig"].axes
    }
    assert legends["ext:spin: r"].startswith("r: 2 of 2")  # every rollout: no success outcome
    assert legends["touch: r"].startswith("r: 1 successful of 2")  # the hand's Fig. 5 selection


def test_return_vs_impact_draws_one_point_per_run_in_newtons(tmp_path, monkeypatch):
    from gentlerl.analysis import figures

    # Impacts logged in the scaled unit (env.force_scale 0.01): 6 and 7 read as 600 and 700 N.
    run = _external_run(tmp_path, "r", 0, (0.0, 50.0, 140.0), [6.0, 7.0])
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["env"]["force_scale"] = 0.01
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    _external_run(tmp_path, "r+rf", 0, (0.0, 0.0, 10.0), [0.0, 0.0])
    drawn = {}
    monkeypatch.setattr(figures, "_save", lambda fig, path: drawn.setdefault("fig", fig))
    figures.plot_return_vs_impact(find_runs([tmp_path]), tmp_path)
    (ax,) = drawn["fig"].axes
    points = sorted(tuple(c.get_offsets()[0]) for c in ax.collections)
    assert points == [(0.0, 10.0), (650.0, 140.0)]  # (median max impact N, mean final return)
    assert ax.get_ylabel() == "final mean return"
