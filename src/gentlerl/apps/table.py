"""``gentlerl table GRID``: the grids' tables moved out of the library in 0.2.0.

The SAC grid's, GentleBench's and Method III's tables with their pre-registered verdicts are the
project's own experiments; each is a script of a checkout (:data:`MOVED`). This command only says
which one to run.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from gentlerl.apps.parsing import command_parser

#: Grid name -> the script that prints its table now.
MOVED: dict[str, str] = {
    "sac": "experiments/sac_grid/table.py",
    "gentlebench": "experiments/gentlebench/table.py",
    "method3": "experiments/method3/table.py",
}


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl table") -> None:
    """Refuse in one line, naming the script that prints the grid's table now."""
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("grid", choices=tuple(MOVED), help="the grid whose table moved")
    parser.add_argument(
        "runs", nargs="?", type=Path, help="the grid's --out folder (e.g. runs/sac)"
    )
    args = parser.parse_args(argv)
    runs = args.runs or "RUNS_DIR"
    raise ValueError(
        f"the {args.grid} grid's table moved out of the library in 0.2.0: run python "
        f"{MOVED[args.grid]} {runs} from a checkout"
    )
