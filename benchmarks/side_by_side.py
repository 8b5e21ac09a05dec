"""Time the same workload in several processes, one block each in turn, under the same load.

A benchmark script that serves (prints ``ready`` once set up, then one rate per line it reads on
stdin) can be run in one process per configuration, each with its own ``PYTHONPATH``: the code
of a git revision (:func:`revision_src`) next to this tree's. Rounds alternate the processes, so a
load that comes and goes on a shared machine hits all of them alike; compare them by the median
of the per-round ratios.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def revision_src(rev: str) -> Iterator[str]:
    """A temporary copy of ``src/`` at git revision ``rev`` (``git archive``): its path."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", rev, "src"], check=True, capture_output=True
        )
        subprocess.run(["tar", "-x", "-C", tmp], input=archive.stdout, check=True)
        yield f"{tmp}/src"


def run_rounds(
    script: Path,
    runs: Mapping[str, tuple[Sequence[str], str]],
    rounds: int,
    envs: Mapping[str, Mapping[str, str]] | None = None,
) -> dict[str, list[float]]:
    """``{name: [rate per round]}`` of ``python script *args`` with ``PYTHONPATH=src``, per run
    (and the run's variables of ``envs``, e.g. a library's knobs, in its environment)."""
    workers = {}
    try:
        for name, (args, src) in runs.items():
            env = {**os.environ, **(envs or {}).get(name, {}), "PYTHONPATH": src}
            cmd = [sys.executable, str(script), *args]
            workers[name] = subprocess.Popen(cmd, env=env, text=True, stdin=-1, stdout=-1)
            start = time.perf_counter()
            if workers[name].stdout.readline().strip() != "ready":
                raise RuntimeError(f"{name}: the worker did not start ({cmd})")
            print(f"{name}: set up and warmed up in {time.perf_counter() - start:.0f} s")
        rates: dict[str, list[float]] = {name: [] for name in workers}
        for r in range(rounds):  # every other round backwards: no process is always first
            for name in list(workers) if r % 2 == 0 else reversed(list(workers)):
                worker = workers[name]
                worker.stdin.write("go\n")
                worker.stdin.flush()
                rates[name].append(float(worker.stdout.readline()))
    finally:
        for worker in workers.values():
            worker.stdin.close()
            worker.wait()
    return rates


def print_table(rates: Mapping[str, list[float]], what: str, unit: str) -> None:
    """Markdown: median rate, its period in ms, and the median per-round ratio to the first run."""
    base = next(iter(rates.values()))
    print(f"\n| {what} | {unit} (median) | ms | x first (median of rounds) | rounds |")
    print("| --- | ---: | ---: | ---: | --- |")
    for name, r in rates.items():
        ratio = statistics.median(a / b for a, b in zip(r, base, strict=True))
        rate, rounds = statistics.median(r), ", ".join(f"{x:.1f}" for x in r)
        print(f"| {name} | {rate:.1f} | {1e3 / rate:.2f} | {ratio:.2f}x | {rounds} |")
