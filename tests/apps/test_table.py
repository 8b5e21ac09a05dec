"""``gentlerl table`` (apps.table): a suite's results file as the safe-RL table, printed or
written whole; every grid's table moved to a checkout's ``experiments/``, and its name is refused
in one line naming the script to run instead."""

from pathlib import Path

import pytest

from gentlerl import cli
from gentlerl.apps.table import MOVED, csv_table

ROOT = Path(__file__).resolve().parents[2]
#: The committed example: a toy run of tests/apps/suite_example/toy.yaml and its table.
EXAMPLE = "tests/apps/suite_example/results.csv"
EXAMPLE_TABLE = ROOT / "tests" / "apps" / "suite_example" / "table.md"


@pytest.mark.parametrize("grid", sorted(MOVED))
def test_each_grid_is_refused_in_one_line_naming_its_script(grid, tmp_path, capsys):
    assert cli.main(["table", grid, str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"run python {MOVED[grid]} {tmp_path} from a checkout" in err
    assert cli.main(["table", grid]) == 1  # no folder: the script's usage
    assert f"run python {MOVED[grid]} RUNS_DIR from a checkout" in capsys.readouterr().err


def test_the_scripts_it_names_exist():
    assert all((ROOT / script).is_file() for script in MOVED.values())


def test_the_committed_example_table_is_what_its_csv_gives(monkeypatch):
    """A hand-edited number in table.md, or a CSV changed without its table, fails here."""
    monkeypatch.chdir(ROOT)
    assert csv_table(EXAMPLE) == EXAMPLE_TABLE.read_text()


def test_a_results_file_is_printed_or_written_whole(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert cli.main(["table", EXAMPLE]) == 0
    assert capsys.readouterr().out == EXAMPLE_TABLE.read_text()
    out = tmp_path / "t.md"
    assert cli.main(["table", EXAMPLE, "--out", str(out)]) == 0
    assert out.read_text() == EXAMPLE_TABLE.read_text()
    assert capsys.readouterr().out == f"wrote {out}\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.csv"], "missing.csv: no such results file"),
        ([EXAMPLE, "--out", "t.txt"], "the file name must end in .md"),
        ([EXAMPLE, "runs"], "a results file's table takes no second argument"),
    ],
)
def test_a_bad_table_command_is_refused_in_one_line_writing_nothing(
    tmp_path, capsys, monkeypatch, args, message
):
    (tmp_path / "tests").symlink_to(ROOT / "tests")
    monkeypatch.chdir(tmp_path)
    assert cli.main(["table", *args]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tests"]
