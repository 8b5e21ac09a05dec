"""``gentlerl plot`` names a malformed file and skips runs that logged nothing, writing nothing on a
refusal."""

from __future__ import annotations

import pytest

from tests.helpers import minimal_run


@pytest.mark.parametrize(
    ("file", "content", "match"),
    [
        ("logs/scalars/eval/success_rate.csv", "1000,0.5\nnot,a,number\n", "success_rate.csv:2"),
        ("config.yaml", "task: [unclosed\n", "config.yaml: not valid YAML"),
        ("config.yaml", "- a list\n", "config.yaml: not a run's config"),
    ],
)
def test_plot_names_a_malformed_file_and_writes_nothing(tmp_path, file, content, match):
    from gentlerl.apps.plot import main as plot

    run = minimal_run(tmp_path / "runs")
    (run / file).write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert "\n" not in str(err.value) and not (tmp_path / "figs").exists()


def test_plot_skips_runs_that_logged_nothing_instead_of_nan_rows(tmp_path, capsys):
    from gentlerl.apps.plot import main as plot

    minimal_run(tmp_path / "runs", seed=0, scalars=None)
    with pytest.raises(FileNotFoundError, match="none of the 1 run"):
        plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert not (tmp_path / "figs").exists()
    minimal_run(tmp_path / "runs", seed=1)
    plot([str(tmp_path / "runs"), "-o", str(tmp_path / "figs")])
    assert "skipped 1 run(s) with nothing logged" in capsys.readouterr().err
