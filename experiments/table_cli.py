"""The command line every experiment's ``table.py`` shares: ``python experiments/<name>/table.py
RUNS_DIR`` prints the markdown table of the runs under ``RUNS_DIR`` with its verdicts."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path


def main(
    table: Callable[[Path], str], description: str, prog: str, argv: Sequence[str] | None = None
) -> None:
    """Print ``table(RUNS_DIR)``; a missing folder or one without the grid's runs is refused in one
    line on stderr (exit status 1)."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("runs", type=Path, help="the grid's --out folder (e.g. runs/sac)")
    args = parser.parse_args(argv)
    try:
        if not args.runs.is_dir():
            raise FileNotFoundError(f"{args.runs}: no such directory")
        text = table(args.runs)
    except (OSError, ValueError) as err:
        sys.exit(f"{prog}: {err}")
    print(text, end="")
