"""``gentlerl table`` (apps.table): every grid's table moved to a checkout's ``experiments/``; the
command refuses in one line naming the script to run instead."""

import pytest

from gentlerl import cli
from gentlerl.apps.table import MOVED


@pytest.mark.parametrize("grid", sorted(MOVED))
def test_each_grid_is_refused_in_one_line_naming_its_script(grid, tmp_path, capsys):
    assert cli.main(["table", grid, str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"run python {MOVED[grid]} {tmp_path} from a checkout" in err
    assert cli.main(["table", grid]) == 1  # no folder: the script's usage
    assert f"run python {MOVED[grid]} RUNS_DIR from a checkout" in capsys.readouterr().err


def test_the_scripts_it_names_exist():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    assert all((root / script).is_file() for script in MOVED.values())
