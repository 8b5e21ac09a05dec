"""``gentlerl table RESULTS.csv``: the safe-RL table of a suite's results; the grids' tables
moved out of the library in 0.2.0.

    gentlerl table runs/after_fix/results.csv --out runs/after_fix/table.md
    gentlerl table runs/after_fix/results.csv --tasks touch,fragile

A results file (``gentlerl suite run``'s ``OUT/results.csv``) gives, per task, each variant's
``return ± std | max impact ± std (N) | success ± std`` over its seeds
(:func:`~gentlerl.analysis.results_table.results_markdown`), printed or written to ``--out``
whole. The table opens with a comment naming this command and the CSV: a test regenerates every
such table of the README and docs from its CSV, so a committed table is never edited by hand.

The SAC grid's, GentleBench's and Method III's tables with their pre-registered verdicts are the
project's own experiments; each is a script of a checkout (:data:`MOVED`): ``gentlerl table
sac`` only says which one to run.
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


def csv_table(
    results: str | Path, source: str | None = None, tasks: Sequence[str] | None = None
) -> str:
    """The markdown table of the results file ``results``, its marker naming ``source`` (default:
    the path as given); ``tasks``: only these tasks (``--tasks``)."""
    from gentlerl.analysis.results import read_results
    from gentlerl.analysis.results_table import results_markdown

    path = Path(results)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such results file (gentlerl suite run writes one)")
    rows = read_results(path)
    return results_markdown(rows, str(results) if source is None else source, tasks)


def command_table(arguments: str) -> str:
    """The table ``gentlerl table ARGUMENTS`` prints, for the arguments a generated table's first
    line names (``RESULTS.csv`` or ``RESULTS.csv --tasks a,b``)."""
    results, _, tasks = arguments.partition(" --tasks ")
    return csv_table(results, tasks=tasks.split(",") if tasks else None)


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl table") -> str:
    """Print (or write to ``--out``) a results file's table; refuse a moved grid's name in one
    line, naming the script that prints its table now."""
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument(
        "results",
        metavar="RESULTS",
        help="a suite's results.csv; or a moved grid's name {" + ",".join(MOVED) + "}",
    )
    parser.add_argument(
        "runs", nargs="?", type=Path, help="with a grid's name: the grid's --out folder"
    )
    parser.add_argument(
        "--tasks",
        type=lambda text: text.split(","),
        help="only these tasks, comma-separated (touch,fragile); the table's first line says so",
    )
    parser.add_argument(
        "--out", type=Path, help="write the table to this .md file (default: print)"
    )
    args = parser.parse_args(argv)
    if args.results in MOVED:
        runs = args.runs or "RUNS_DIR"
        raise ValueError(
            f"the {args.results} grid's table moved out of the library in 0.2.0: run python "
            f"{MOVED[args.results]} {runs} from a checkout"
        )
    if args.runs is not None:
        raise ValueError(f"{args.runs}: a results file's table takes no second argument")
    if args.out is not None:
        from gentlerl.apps.outputs import check_output_file

        check_output_file(args.out, (".md",))
    text = csv_table(args.results, tasks=args.tasks)
    if args.out is None:
        print(text, end="")
    else:
        from gentlerl.files import write_atomic

        write_atomic(args.out, text)
        print(f"wrote {args.out}")
    return text
