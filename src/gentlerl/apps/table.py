"""A pre-registered grid's table and verdicts: ``gentlerl table {sac,gentlebench,method3} RUNS_DIR``.

``sac``: the SAC grid of docs/SAC.md (``recipes/grids/sac_grid.sh``), from each run's
``final_eval.json``; ``gentlebench``: GentleBench of docs/GENTLEBENCH.md
(``recipes/grids/gentlebench.sh``), from each run's ``final_eval_episodes.csv``; ``method3``: its
Method III amendment (``recipes/grids/method3.sh``). Prints a
markdown table with each pre-registered verdict (:mod:`gentlerl.analysis.criteria`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from gentlerl.analysis.grid_tables import gentlebench_table, sac_table
from gentlerl.analysis.method3 import method3_table
from gentlerl.apps.parsing import command_parser

#: Grid name -> the table of its runs under a folder.
TABLES: dict[str, Callable[[Path], str]] = {
    "sac": sac_table,
    "gentlebench": gentlebench_table,
    "method3": method3_table,
}


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl table") -> None:
    """Print the table and verdicts of the grid named on the command line."""
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("grid", choices=tuple(TABLES), help="which grid's criteria judge the runs")
    parser.add_argument("runs", type=Path, help="the grid's --out folder (e.g. runs/sac)")
    args = parser.parse_args(argv)
    if not args.runs.is_dir():
        raise FileNotFoundError(f"{args.runs}: no such directory")
    print(TABLES[args.grid](args.runs), end="")
