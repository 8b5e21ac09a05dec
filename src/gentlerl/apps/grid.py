"""A sweep's grid points and how each one runs: what the local runner and the Ray backend share.

:func:`expand` turns a sweep file's grid into :class:`GridRun` points, each a ``gentlerl-train``
process with a deterministic ``run_dir``; :func:`pending` is the points without their run's
``DONE`` marker; :func:`run_point` runs one with ``resume=auto``; :func:`run_grid` is the local
backend (a pool of ``workers`` points at a time). :mod:`gentlerl.apps.grid_ray` runs the
same points as Ray tasks.
"""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from gentlerl.config.layout import RunLayout
from gentlerl.files import open_append, open_checked


@dataclass(frozen=True)
class GridRun:
    """One grid point: its ``key=value`` overrides and the run directory it trains in."""

    overrides: tuple[tuple[str, Any], ...]
    run_dir: Path
    #: A recipe script to run instead of the installed ``gentlerl-train`` app (on a Ray
    #: cluster, None runs the worker node's installed gentlerl).
    script: Path | None = None

    def command(self, extra: Sequence[str] = ()) -> list[str]:
        """The trainer's command line: the overrides, ``extra``, then ``run_dir``."""
        args = [f"{k}={_format(v)}" for k, v in self.overrides]
        # None: the installed app, wherever gentlerl is installed (no path to recipes/).
        app = [str(self.script)] if self.script else ["-m", "gentlerl.apps.train"]
        return [sys.executable, *app, *args, *extra, f"run_dir={self.run_dir}"]


def _format(value: Any) -> str:
    if isinstance(value, list | tuple):
        return "[" + ",".join(_format(v) for v in value) + "]"
    return "null" if value is None else str(value)


def _slug(value: Any) -> str:
    if isinstance(value, list | tuple):
        return "-".join(_slug(v) for v in value)
    return str(value)


#: The most points a sweep's grid may have (counted before it is expanded).
MAX_GRID_POINTS = 10_000


def expand(grid: dict[str, list[Any]], out: Path) -> list[GridRun]:
    """Every grid point (lam_prime dropped where the variant has no penalty surprise),
    deduplicated; a grid of over :data:`MAX_GRID_POINTS` points is refused before expanding."""
    size = math.prod(len(values) for values in grid.values())
    if size > MAX_GRID_POINTS:
        counts = " x ".join(str(len(values)) for values in grid.values())
        raise ValueError(f"the grid has {counts} = {size:,} points, over {MAX_GRID_POINTS:,}")
    runs, seen = [], set()
    names = list(grid)
    for values in itertools.product(*(grid[n] for n in names)):
        point = dict(zip(names, values, strict=True))
        if "rsp" not in str(point.get("variant", "rsp")):
            point.pop("gentleness.lam_prime", None)
        key = tuple(point.items())
        if repr(key) in seen:
            continue
        seen.add(repr(key))
        # No commas, brackets or '=' in the directory name: hydra would parse them in run_dir=...
        name = "_".join(f"{k.rsplit('.', 1)[-1]}-{_slug(v)}" for k, v in key)
        runs.append(GridRun(key, _inside(out, name)))
    return runs


def _inside(out: Path, name: str) -> Path:
    """``out / name``, refused unless it is a folder directly under ``out``."""
    run_dir = out / name
    if "/" in name or os.sep in name or run_dir.resolve().parent != out.resolve():
        raise ValueError(f"grid point folder {name!r} would not be directly under {out}")
    if len(name.encode()) > 255:
        raise ValueError(f"grid point folder {name[:60]!r}... is longer than 255 bytes")
    return run_dir


def restrict(grid: dict[str, list[Any]], only: Sequence[str]) -> dict[str, list[Any]]:
    """The grid with parameter ``KEY`` cut to the values listed in each ``KEY=V1,V2,...`` of
    ``only`` that it has (values compared as they print on a command line: ``seed=0,1``,
    ``variant=r+rf+rsp``). A ``KEY`` the sweep does not vary, or a cut that leaves nothing, is an
    error."""
    grid = dict(grid)
    for item in only:
        key, sep, values = item.partition("=")
        if not sep or key not in grid:
            raise ValueError(
                f"--only {item!r}: expected KEY=V1,V2,... with KEY one of {sorted(grid)}"
            )
        wanted = set(values.split(","))
        kept = [v for v in grid[key] if _format(v) in wanted]
        if not kept:
            raise ValueError(
                f"--only {item!r} keeps none of {key}'s values {[_format(v) for v in grid[key]]}"
            )
        grid[key] = kept
    return grid


def run_grid(
    runs: Sequence[GridRun], workers: int = 1, extra: Sequence[str] = (), dry_run: bool = False
) -> dict[str, int]:
    """Run (or, ``dry_run``, print) the grid; counts ``done``/``skipped``/``failed``/``planned``.

    Interrupted (Ctrl-C, ``SIGTERM`` through ``gentlerl sweep``), it kills the process group of every
    trainer still running, so no orphaned trainer keeps writing its run directory."""
    todo = pending(runs)
    counts = {"skipped": len(runs) - len(todo), "done": 0, "failed": 0, "planned": 0}
    _STOPPING.clear()
    with ThreadPoolExecutor(max_workers=max(workers, 1)) as pool:
        try:
            for code in pool.map(lambda run: run_point(run, extra, dry_run), todo):
                counts["planned" if dry_run else "done" if code == 0 else "failed"] += 1
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)  # no queued point starts
            stop_trainers()
            raise
    return counts


def pending(runs: Sequence[GridRun]) -> list[GridRun]:
    """The runs without a ``DONE`` marker."""
    return [r for r in runs if not RunLayout(r.run_dir).done.exists()]


def run_point(run: GridRun, extra: Sequence[str] = (), dry_run: bool = False) -> int:
    """Run one grid point with ``resume=auto`` (continued from its checkpoint, or started again
    when it was interrupted before its first one); the recipe's exit code.

    Output goes to ``run_dir/stdout.log``; a failure's last line is printed here too. The Ray
    backend calls this on the worker node.
    """
    command = run.command([*extra, "resume=auto"])
    print(" ".join(command), flush=True)
    if dry_run:
        return 0
    run.run_dir.mkdir(parents=True, exist_ok=True)
    log_path = RunLayout(run.run_dir).stdout
    with open_append(log_path) as log:  # a planted link is refused, not written through
        code = _call(command, log)
    if code != 0:
        lines = _tail(log_path).strip().splitlines()
        print(f"{run.run_dir}: exit {code}: {lines[-1] if lines else ''}", file=sys.stderr)
    return code


def _tail(path: Path, size: int = 4096) -> str:
    """The last ``size`` bytes of the log ``path`` (a trainer's stdout may be long)."""
    with open_checked(path, cap=None, binary=True) as f:
        f.seek(max(0, os.fstat(f.fileno()).st_size - size))
        return f.read(size).decode(errors="replace")


#: Trainers running now (their process groups are killed when the sweep is interrupted).
_LIVE: set[subprocess.Popen] = set()
_LIVE_LOCK = threading.Lock()
#: Set by :func:`stop_trainers`: a point about to start does not.
_STOPPING = threading.Event()


def _call(command: list[str], log: IO[str]) -> int:
    """Run ``command`` in its own process group (its collector workers with it); the group is
    killed if this call is interrupted (Ctrl-C, a cancelled Ray task)."""
    with _LIVE_LOCK:
        if _STOPPING.is_set():
            return -signal.SIGTERM
        proc = subprocess.Popen(
            command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
        _LIVE.add(proc)
    try:
        return proc.wait()
    except BaseException:
        _kill_group(proc)
        raise
    finally:
        with _LIVE_LOCK:
            _LIVE.discard(proc)


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=30)
    except ProcessLookupError:
        pass
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)


def stop_trainers() -> None:
    """Kill the process group of every trainer this sweep still runs."""
    with _LIVE_LOCK:
        _STOPPING.set()
        live = list(_LIVE)
    for proc in live:
        _kill_group(proc)
