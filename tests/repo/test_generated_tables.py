"""Every table ``gentlerl table`` generated into the README and docs is what its CSV gives now:
a hand-edited number, or a CSV changed without its table, fails here (rerun the command the
table's first line names, from the repository's root)."""

import re
from pathlib import Path

import pytest

from gentlerl.analysis.results_table import generated_tables
from gentlerl.apps.table import command_table, csv_table

ROOT = Path(__file__).resolve().parents[2]
#: The markdown files a results table may be generated into.
PLACES = ("*.md", "docs/**/*.md", "benchmarks/**/*.md", "experiments/**/*.md", "tests/**/*.md")


def _tables() -> list[tuple[Path, str, str]]:
    found = []
    for pattern in PLACES:
        for path in sorted(ROOT.glob(pattern)):
            found += [(path, source, table) for source, table in generated_tables(path.read_text())]
    return found


TABLES = _tables()


def test_the_committed_example_is_among_the_generated_tables():
    names = {(path.relative_to(ROOT).as_posix(), source) for path, source, _ in TABLES}
    example = ("tests/apps/suite_example/table.md", "tests/apps/suite_example/results.csv")
    assert example in names


@pytest.mark.parametrize(
    ("path", "source", "table"), TABLES, ids=[f"{p.name}:{s}" for p, s, _ in TABLES]
)
def test_each_generated_table_is_what_its_csv_gives(path, source, table, monkeypatch):
    monkeypatch.chdir(ROOT)  # the CSV as the command named it, from the repository's root
    csv = source.partition(" --tasks ")[0]
    assert (ROOT / csv).is_file(), f"{path}: its table names {csv}, which is not committed"
    assert command_table(source) == table, (
        f"{path}: the table differs from what {source} gives: run gentlerl table {source}"
    )


def test_a_hand_edited_number_is_caught(monkeypatch):
    monkeypatch.chdir(ROOT)
    path, source, table = next(t for t in TABLES if t[0].name == "table.md")
    row = next(line for line in table.splitlines() if re.match(r"\| [^-v]", line))
    one_digit_more = re.sub(r"\d", lambda m: str((int(m[0]) + 1) % 10), row, count=1)
    edited = table.replace(row, one_digit_more)
    assert edited != table and csv_table(source) != edited
