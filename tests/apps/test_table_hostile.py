"""``gentlerl table`` on any CSV (issue 63): total (a NaN, an inf, ``1_000`` or another script's
digits refused in one line, never a traceback), linear in the rows, and a label cannot forge a
row of the markdown; the results files gentlerl writes are formula-safe."""

import csv
import time

import pytest

from gentlerl import cli
from gentlerl.analysis.results import RESULT_COLUMNS, read_results, results_text
from gentlerl.analysis.results_table import results_markdown


def _row(**values):
    row = dict.fromkeys(RESULT_COLUMNS, "")
    row.update(suite="s", cell="t/r", task="t", variant="r", seed="0", frames="100")
    row.update({k: str(v) for k, v in values.items()})
    return row


def _csv(path, rows):
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, RESULT_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    return path


@pytest.mark.parametrize(
    ("column", "text"),
    [
        ("return", "nan"), ("return", "inf"), ("max_impact", "-Infinity"),
        ("frames", "1_000"), ("return", "1_0.5"),
        ("seed", "\u0661\u0662"),  # Arabic-Indic digits: int() reads 12
        ("return", "\u0661.5"), ("frames", "9" * 5000),
    ],
)  # fmt: skip
def test_a_cell_that_is_not_an_ascii_finite_number_is_one_line(tmp_path, capsys, column, text):
    """The findings: NaN or inf crashed ('float' object has no attribute 'numerator'); ``1_000``
    and Arabic-Indic digits read as numbers."""
    path = _csv(tmp_path / "r.csv", [_row(**{column: text})])
    assert cli.main(["table", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"r.csv:2: {column}=" in err and "is not a number" in err


def test_a_label_with_a_pipe_or_a_newline_cannot_forge_a_row(tmp_path):
    """The finding: a variant ``a | 9 | 9 | 9 | 1 |\\n| forged`` added a row to the table."""
    forged = "x | 9.00 | 9.00 | 9.00 | 1 |\n| forged"
    path = _csv(
        tmp_path / "r.csv",
        [_row(variant=forged, cell="t/x", **{"return": 1.0}),
         _row(task="t<!-- end of the generated table -->", cell="u/r", **{"return": 2.0})],
    )  # fmt: skip
    text = results_markdown(read_results(path), "r.csv")
    rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == 4  # two headers, two variants: nothing forged
    assert r"| x \| 9.00 \| 9.00 \| 9.00 \| 1 \|\x0a\| forged |" in text
    assert text.count("<!--") == 2 and "&lt;!-- end" in text  # its own two markers only


def test_fifty_thousand_tasks_take_well_under_a_few_seconds(tmp_path):
    """The finding: 50,000 tasks took over 60 s (every task filtered every row again)."""
    rows = [
        {**_row(task=f"t{i}", cell=f"t{i}/r", seed=s), "return": 1.0 + s, "seed": s,
         "frames": 100, "success_rate": None, "broken_rate": None, "max_impact": None,
         "wall_s": None, "grouped": None, "cost": None}
        for i in range(50_000) for s in (0, 1)
    ]  # fmt: skip
    start = time.perf_counter()
    text = results_markdown(rows, "r.csv")
    took = time.perf_counter() - start
    assert text.count("**t") == 50_000 and "| r | 1.50 ± 0.71 |" in text
    assert took < 5.0, took  # about 0.5 s on a loaded 2-core machine


@pytest.mark.parametrize("column", ["suite", "cell", "task", "variant", "commit"])
@pytest.mark.parametrize("start", ["=", "+", "-", "@"])
def test_a_results_file_never_writes_a_formula(column, start):
    """The finding: folder names reached results.csv as written (formula injection)."""
    typed = {"suite": "s", "cell": "t/r", "task": "t", "variant": "r", "seed": 0, "frames": 100}
    row = {**typed, column: f'{start}HYPERLINK("http://x")'}
    with pytest.raises(ValueError, match=f"{column} .* starts with '\\{start}': a spreadsheet"):
        results_text([row])
    with pytest.raises(ValueError, match="return: nan is not a finite number"):
        results_text([{**typed, "return": float("nan")}])
    quoted = results_text([{**typed, "variant": 'a,"b"\nc'}])
    assert '"a,""b""\nc"' in quoted  # a comma, a quote, a newline: quoted


def test_a_summary_csv_shows_a_planted_formula_as_text():
    """``gentlerl plot``'s summary.csv holds labels read from run configs (a crafted config.yaml's
    variant ``=HYPERLINK(...)``): shown as text, numbers left alone."""
    from gentlerl.files import spreadsheet_safe

    assert spreadsheet_safe('=HYPERLINK("x")') == '\'=HYPERLINK("x")'
    assert spreadsheet_safe("@SUM(A1)") == "'@SUM(A1)" and spreadsheet_safe("+cmd") == "'+cmd"
    assert spreadsheet_safe("-1.5") == "-1.5" and spreadsheet_safe(-2.0) == -2.0
    assert spreadsheet_safe("r+rf") == "r+rf"
