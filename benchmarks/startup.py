"""How long a newcomer waits for ``gentlerl train --help`` and for a refused config.

Each command runs ``--repeats`` times as a fresh process (as a user types it); the table gives
the best and the median wall time, and for scale how long importing TorchRL alone takes. With
``--record`` the table, with the machine, its load and the date, is appended to
``benchmarks/RESULTS.md``.

Run: ``python benchmarks/startup.py [--repeats 5] [--record]``.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"

#: What is timed: a label and the command's arguments after the interpreter.
COMMANDS = {
    "`gentlerl train --help`": "-m gentlerl train --help",
    "`gentlerl train variant=bogus` (refused)": "-m gentlerl train variant=bogus",
    "`gentlerl train collector.total_frames=-5` (refused)": "-m gentlerl train "
    "collector.total_frames=-5",
    "for scale: `python -c 'import torchrl'`": "-c 'import torchrl'",
}


def wall_times(args: str, repeats: int, cwd: str) -> list[float]:
    """Seconds each of ``repeats`` fresh ``python ARGS`` processes took, start to exit."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        command = [sys.executable, *shlex.split(args)]
        subprocess.run(command, cwd=cwd, capture_output=True, check=False)
        times.append(time.perf_counter() - start)
    return times


def table(repeats: int) -> str:
    """The markdown section: machine, load before and after, date, then one row per command."""
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as cwd:  # a refusal may leave empty run folders
        rows = [(label, wall_times(args, repeats, cwd)) for label, args in COMMANDS.items()]
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    lines = [
        "## startup: help and refusals (`benchmarks/startup.py`)",
        "",
        f"{machine}, Python {platform.python_version()}, {now}, load average "
        f"{load_before:.1f} before / {os.getloadavg()[0]:.1f} after; {repeats} fresh processes each.",
        "",
        "| command | best s | median s |",
        "| --- | ---: | ---: |",
    ]
    lines += [f"| {label} | {min(t):.2f} | {statistics.median(t):.2f} |" for label, t in rows]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--record", action="store_true", help=f"append the table to {RESULTS}")
    args = parser.parse_args()
    text = table(args.repeats)
    print(text)
    if args.record:
        with RESULTS.open("a") as f:
            f.write("\n" + text)


if __name__ == "__main__":
    main()
