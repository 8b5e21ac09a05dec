"""Paper-style figures and the summary table of runs: ``gentlerl plot RUN_DIR... -o OUT``.

The figures and files are those of :mod:`gentlerl.analysis.figures` (:func:`write_figures`): the
impact histograms (paper Fig. 3), the final policies' impacts (Fig. 5), learning curves (Fig. 4),
reward components (Fig. 6), return vs impact, and ``summary.csv`` / ``summary.md``. A sweep file
stands for its runs' folder under ``--sweeps-out``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

from gentlerl.analysis.figures import write_figures
from gentlerl.analysis.runs import find_runs
from gentlerl.analysis.summary import format_table, summary_table
from gentlerl.apps.parsing import command_parser


def build_parser(prog: str = "gentlerl plot") -> argparse.ArgumentParser:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument(
        "runs",
        nargs="+",
        help="run directories, folders of runs, or sweep files (recipes/sweeps/NAME.yaml: the "
        "runs of `gentlerl sweep` under SWEEPS_OUT/NAME)",
    )
    parser.add_argument("-o", "--out", default="figures", help="output folder for the PNGs")
    parser.add_argument(
        "--sweeps-out", default="runs/sweeps", help="where `gentlerl sweep --out` put its runs"
    )
    return parser


def resolve_run_paths(paths: Iterable[str], sweeps_out: str | Path) -> list[Path]:
    """Run folders as given, with each sweep file replaced by its runs' folder."""
    resolved = []
    for path in map(Path, paths):
        is_sweep = path.suffix in (".yaml", ".yml") and path.is_file()
        resolved.append(Path(sweeps_out) / path.stem if is_sweep else path)
    return resolved


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl plot") -> None:
    """Write the figures and the summary table of the runs named on the command line."""
    args = build_parser(prog).parse_args(argv)
    found = find_runs(resolve_run_paths(args.runs, args.sweeps_out))
    # A run that logged nothing yet (refused, or interrupted at once) would be a row of nan.
    runs = [run for run in found if run.scalars]
    empty = [str(run.path) for run in found if not run.scalars]
    if empty:
        print(f"{prog}: skipped {len(empty)} run(s) with nothing logged: {empty}", file=sys.stderr)
    if not runs:
        raise FileNotFoundError(f"none of the {len(found)} run(s) found has logged anything")
    out = Path(args.out)
    for path in write_figures(runs, out):
        print(path)
    print(format_table(summary_table(runs)))
