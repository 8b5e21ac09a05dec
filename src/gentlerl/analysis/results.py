"""A benchmark suite's results file: one row per run, what its final evaluation measured.

``gentlerl suite run`` writes ``OUT/results.csv`` (:data:`RESULT_COLUMNS`, one row per run of
each cell) and ``gentlerl table`` reads it back (:func:`read_results`). A row's numbers come from
the run directory (:func:`run_result`): the final evaluation's episodes (the last in-loop
evaluation, at ``collector.total_frames``, in ``eval_episodes.csv``: noise-free episodes of the
final actor) averaged as the trainer's summary averages them, and the training wall clock the
run logged last (``train/wall_s``). An env without a success outcome (dm_control's finger)
leaves ``success_rate`` and ``broken_rate`` empty.
"""

from __future__ import annotations

import csv
import io
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gentlerl.analysis.runs import final_eval_episodes, load_run
from gentlerl.files import FORMULA_START, open_checked, write_atomic

#: The results file's columns, in order: which run (suite, cell = task/variant, seed), how long
#: it trained (frames), its final evaluation (mean return, success and broken rates, mean of the
#: episodes' largest impact in N), its training wall clock (s; a seed group's seeds share one
#: clock), whether its cell ran as one seed group (1) or seed by seed (0), what measured it
#: (the package version, the git commit, the UTC date), and the final evaluation's mean episode
#: cost (steps of violation, :func:`~gentlerl.functional.excess_cost` summed; empty for a run
#: without ``gentleness.tolerance``).
RESULT_COLUMNS = (
    "suite",
    "cell",
    "task",
    "variant",
    "seed",
    "frames",
    "return",
    "success_rate",
    "broken_rate",
    "max_impact",
    "wall_s",
    "grouped",
    "version",
    "commit",
    "date",
    "cost",
)
#: Columns a results file written before them may lack (read as not measured).
ADDED_COLUMNS = ("cost",)
#: Columns holding a number; an empty one is "not measured" (``None``).
NUMERIC = (
    "seed",
    "frames",
    "return",
    "success_rate",
    "broken_rate",
    "max_impact",
    "wall_s",
    "grouped",
    "cost",
)
#: Numeric columns holding integers.
INTEGER = ("seed", "frames", "grouped")
#: A number as a results file writes it: ASCII digits only (no ``1_000``, no other scripts'
#: digits, which Python's ``int`` / ``float`` would take), finite (no ``nan`` / ``inf``).
_INTEGER = re.compile(r"[+-]?[0-9]+", re.ASCII)
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)
#: The most rows a results file may hold (a suite of 64 cells x 64 seeds is 4,096).
MAX_ROWS = 100_000


def _mean(values: Sequence[float]) -> float | None:
    """The mean of ``values``, added up in order as the trainer's summary does; ``None`` if any
    is NaN (the env has no such outcome) or there are none."""
    if not len(values) or any(math.isnan(v) for v in values):
        return None
    return sum(float(v) for v in values) / len(values)


def run_result(run_dir: str | Path) -> dict[str, float | None]:
    """``frames``, ``return``, ``success_rate``, ``broken_rate``, ``max_impact`` and ``cost``
    (``None`` where the run measured none) of the run's final evaluation and its ``wall_s``,
    read from the run directory (a ``ValueError`` naming
    it when it holds no evaluation)."""
    run = load_run(run_dir)
    rows = final_eval_episodes(run)
    if not len(rows):
        raise ValueError(
            f"{run_dir}: no evaluation episodes (eval_episodes.csv): not a finished run"
        )
    _, wall = run.scalars.get("train/wall_s", ((), ()))
    return {
        "frames": int(rows["frames"][0]),
        # numpy.genfromtxt renames the column "return", a python keyword, to "return_"
        "return": _mean(rows["return_"]),
        "success_rate": _mean(rows["success"]),
        "broken_rate": _mean(rows["broken"]),
        "max_impact": _mean(rows["max_impact"]),
        "wall_s": float(wall[-1]) if len(wall) else None,
        "cost": _mean(rows["cost"]) if "cost" in (rows.dtype.names or ()) else None,
    }


def _text(value: Any, column: str = "") -> str:
    """A CSV field: ``repr`` of a float (read back exactly), empty for ``None``; a number column
    holds a finite number, and a text cell never starts as a formula (:func:`formula_safe`)."""
    if value is None:
        return ""
    if column in NUMERIC:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ValueError(f"results column {column}: {value!r:.40} is not a finite number")
        return repr(value) if isinstance(value, float) else str(value)
    return formula_safe(str(value), column)


def formula_safe(text: str, column: str = "cell") -> str:
    """``text`` for a CSV cell a spreadsheet may open, refused (``ValueError``) when it starts
    as a formula would (:data:`FORMULA_START`): gentlerl's labels never do, so such a cell is a
    planted name (a folder ``=HYPERLINK(...)``), not data."""
    if text.startswith(FORMULA_START):
        raise ValueError(
            f"{column} {text[:40]!r} starts with {text[:1]!r}: a spreadsheet would run it as a "
            "formula; gentlerl writes no such cell"
        )
    return text


def results_text(rows: Sequence[Mapping[str, Any]]) -> str:
    """``rows`` as the results file's text (header first, :data:`RESULT_COLUMNS` in order; the
    csv module quotes a field holding a comma, a quote or a newline)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(RESULT_COLUMNS)
    writer.writerows([_text(row.get(c), c) for c in RESULT_COLUMNS] for row in rows)
    return out.getvalue()


def write_results(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """Write ``rows`` to ``path`` whole (a temporary file renamed over it: never half-written)."""
    write_atomic(path, results_text(rows))


def _number(text: str, column: str, where: str) -> float | int | None:
    if text == "":
        return None
    pattern = _INTEGER if column in INTEGER else _FLOAT
    if not pattern.fullmatch(text) or not math.isfinite(value := float(text)):
        kind = "an integer" if column in INTEGER else "finite"
        raise ValueError(
            f"{where}: {column}={text[:40]!r} is not a number ({kind}, in ASCII digits; empty: "
            "not measured)"
        )
    return int(text) if column in INTEGER else value


def read_results(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a results file, numbers as numbers (empty: ``None``); refused in one line
    naming the file (and line) when a column is missing, a number is not one, or a run
    (suite, cell, seed) appears twice."""
    path = Path(path)
    with open_checked(path, newline="", errors="replace") as f:
        reader = csv.DictReader(f)
        held = tuple(reader.fieldnames or ())
        missing = [c for c in RESULT_COLUMNS if c not in held and c not in ADDED_COLUMNS]
        if missing:
            raise ValueError(f"{path}: not a suite's results file (no column {', '.join(missing)})")
        rows, seen = [], set()
        for line, raw in enumerate(reader, 2):
            if line > MAX_ROWS + 1:
                raise ValueError(f"{path}: more than {MAX_ROWS:,} rows")
            where = f"{path}:{line}"
            if None in raw or any(raw[c] is None for c in held):
                raise ValueError(f"{where}: expected {len(held)} fields")
            row: dict[str, Any] = {c: raw.get(c, "") for c in RESULT_COLUMNS}
            for column in NUMERIC:
                row[column] = _number(row[column], column, where)
            if row["seed"] is None:
                raise ValueError(f"{where}: the seed is empty")
            key = (row["suite"], row["cell"], row["seed"])
            if key in seen:
                raise ValueError(f"{where}: run {row['cell']} seed {row['seed']} appears twice")
            seen.add(key)
            rows.append(row)
    return rows
