"""The safe-RL table of a results file (analysis.results_table): mean ± sample std over seeds."""

import pytest

from gentlerl.analysis.results_table import (
    END,
    GENERATED,
    format_mean_std,
    generated_tables,
    mean_std,
    results_markdown,
)


def test_the_std_is_the_sample_one_over_three_seeds():
    # success 1, 0.5, 0: mean 0.5; squared deviations 0.25 + 0 + 0.25 = 0.5, over n - 1 = 2:
    # variance 0.25, std 0.5 (the population std, over n = 3, would be 0.41)
    assert mean_std([1.0, 0.5, 0.0]) == (0.5, 0.5)
    assert format_mean_std([1.0, 0.5, 0.0]) == "0.50 ± 0.50"
    # max impacts 1.31, 1.33, 1.61 N: mean 1.4167, deviations -0.1067, -0.0867, 0.1933:
    # squares 0.011378 + 0.007511 + 0.037378 = 0.056267, / 2 = 0.028133, sqrt 0.1677
    assert format_mean_std([1.31, 1.33, 1.61]) == "1.42 ± 0.17"
    assert format_mean_std([1.31, 1.33, 1.61], digits=3) == "1.417 ± 0.168"


def test_one_seed_none_and_missing_seeds_are_shown_as_such():
    assert format_mean_std([2.5]) == "2.50"  # one seed: no std
    assert format_mean_std([None, None, None]) == "—"  # an env without success
    assert format_mean_std([1.0, None, 0.0]) == "0.50 ± 0.71 (2 seeds)"
    assert format_mean_std([-0.001, 0.0, 0.0]) == "0.00 ± 0.00"  # never "-0.00"
    with pytest.raises(ValueError, match="at least one value"):
        mean_std([])


def _row(task, variant, seed, ret, impact, success, suite="s", frames=30000):
    return dict(
        suite=suite, task=task, variant=variant, seed=seed, frames=frames,
        **{"return": ret, "max_impact": impact, "success_rate": success},
    )  # fmt: skip


def test_the_table_has_a_section_per_task_and_a_row_per_variant_in_the_csvs_order():
    rows = [_row("touch", "r+rf+rsp", s, 1.0, m, 1.0) for s, m in enumerate((1.31, 1.33, 1.61))] + [
        _row("touch", "r", s, 1.0, 6.75, 1.0) for s in range(3)
    ]
    rows += [
        _row("finger-spin", "r", s, r, 788.0, None, frames=50000) for s, r in enumerate((1, 2))
    ]
    text = results_markdown(rows, "runs/x/results.csv")
    lines = text.splitlines()
    assert lines[0] == GENERATED.format(source="runs/x/results.csv") and lines[-1] == END
    assert lines[4:10] == [
        "**touch**, 30000 frames",
        "",
        "| variant | return ± std | max impact ± std (N) | success ± std | seeds |",
        "| --- | --- | --- | --- | --- |",
        "| r+rf+rsp | 1.00 ± 0.00 | 1.42 ± 0.17 | 1.00 ± 0.00 | 3 |",
        "| r | 1.00 ± 0.00 | 6.75 ± 0.00 | 1.00 ± 0.00 | 3 |",
    ]
    assert "**finger-spin**, 50000 frames" in lines
    assert "| r | 1.50 ± 0.71 | 788.00 ± 0.00 | — | 2 |" in lines
    assert results_markdown(list(rows), "runs/x/results.csv") == text  # deterministic
    two = rows + [_row("touch", "r", 0, 0.0, 1.0, 0.0, suite="t")]
    assert "**t: touch**, 30000 frames" in results_markdown(two, "a.csv")


def test_generated_tables_are_found_in_a_text_with_their_csv():
    table = results_markdown([_row("touch", "r", 0, 1.0, 2.0, 1.0)], "docs/a.csv")
    text = f"# Results\n\nbefore\n\n{table}\nafter\n"
    assert generated_tables(text) == [("docs/a.csv", table)]
    assert generated_tables("no table here") == []


def test_tasks_limit_the_table_to_those_and_its_first_line_says_so():
    rows = [_row("touch", "r", 0, 1.0, 6.0, 1.0), _row("fragile", "r", 0, 0.0, 9.0, 0.0)]
    rows.append(_row("finger-spin", "r", 0, 80.0, 490.0, None, frames=50000))
    text = results_markdown(rows, "a.csv", tasks=["fragile", "touch"])
    lines = text.splitlines()
    assert lines[0] == GENERATED.format(source="a.csv --tasks fragile,touch")
    # the CSV's order, not the option's; the other task left out
    assert [ln for ln in lines if ln.startswith("**")] == [
        "**touch**, 30000 frames",
        "**fragile**, 30000 frames",
    ]
    assert generated_tables(f"x\n{text}y\n") == [("a.csv --tasks fragile,touch", text)]
    with pytest.raises(ValueError, match=r"^a.csv: --tasks touch,spin: no rows of \['spin'\]; it "
                       r"holds touch, fragile, finger-spin$"):  # fmt: skip
        results_markdown(rows, "a.csv", tasks=["touch", "spin"])


def test_the_cost_column_is_shown_for_a_task_whose_runs_measured_one():
    rows = [
        _row("spin", "gentle", s, 500.0, 20.0, None) | {"cost": c} for s, c in enumerate((10, 30))
    ]
    rows += [_row("touch", "r", 0, 1.0, 6.0, 1.0)]  # no tolerance: no cost column
    lines = results_markdown(rows, "a.csv").splitlines()
    assert "cost: the episodes' steps of violation" in lines[2]
    header = "| variant | return ± std | max impact ± std (N) | success ± std | cost ± std (steps) | seeds |"
    assert header in lines
    # costs 10 and 30: mean 20, sample std sqrt(((-10)^2 + 10^2) / 1) = 14.14
    assert "| gentle | 500.00 ± 0.00 | 20.00 ± 0.00 | — | 20.00 ± 14.14 | 2 |" in lines
    assert "| r | 1.00 | 6.00 | 1.00 | 1 |" in lines
