"""Run a wandb sweep file's grid locally, without a wandb server.

    gentlerl sweep recipes/sweeps/fig4_touch.yaml --workers 2 --out runs/sweeps --figures figs

Each grid point becomes one ``python -m gentlerl.training.cli key=value ...`` process with a
deterministic ``run_dir`` (``OUT/<sweep>/<key-value_...>``). The runner is resumable: a run whose
``DONE`` marker exists is skipped, the others run with ``resume=auto`` (continued from their
checkpoint, or started again if interrupted before their first). Grid points that differ only in
``lam_prime`` for a variant without penalty surprise are run once (the parameter does not affect
them). Keys and values are checked before anything runs (:mod:`gentlerl.sweep_files`), and each
point's config is validated; an interrupted sweep kills its trainers' process groups. The same files work with ``wandb sweep`` / ``wandb agent``.
``--backend ray`` runs each grid point as a Ray task instead, on a local Ray or a cluster
(:mod:`gentlerl.distributed.sweeps`, docs/DISTRIBUTED.md).
"""

from __future__ import annotations

import argparse
import itertools
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

from gentlerl.cli import command_parser
from gentlerl.sweep_files import check_set, load_sweep, point_problem
from gentlerl.training.loop import DONE_MARKER


@dataclass(frozen=True)
class GridRun:
    overrides: tuple[tuple[str, Any], ...]
    run_dir: Path
    #: A recipe script to run instead of the installed ``gentlerl-train`` app (on a Ray
    #: cluster, None runs the worker node's installed gentlerl).
    script: Path | None = None

    def command(self, extra: Sequence[str] = ()) -> list[str]:
        args = [f"{k}={_format(v)}" for k, v in self.overrides]
        # None: the installed app, wherever gentlerl is installed (no path to recipes/).
        app = [str(self.script)] if self.script else ["-m", "gentlerl.training.cli"]
        return [sys.executable, *app, *args, *extra, f"run_dir={self.run_dir}"]


def _format(value: Any) -> str:
    if isinstance(value, list | tuple):
        return "[" + ",".join(_format(v) for v in value) + "]"
    return "null" if value is None else str(value)


def _slug(value: Any) -> str:
    if isinstance(value, list | tuple):
        return "-".join(_slug(v) for v in value)
    return str(value)


def expand(grid: dict[str, list[Any]], out: Path) -> list[GridRun]:
    """Every grid point (lam_prime dropped where the variant has no penalty surprise), deduplicated."""
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

    Interrupted (Ctrl-C, ``SIGTERM`` through :func:`main`), it kills the process group of every
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
    return [r for r in runs if not (r.run_dir / DONE_MARKER).exists()]


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
    log_path = run.run_dir / "stdout.log"
    with log_path.open("a") as log:
        code = _call(command, log)
    if code != 0:
        lines = log_path.read_text(errors="replace").strip().splitlines()
        print(f"{run.run_dir}: exit {code}: {lines[-1] if lines else ''}", file=sys.stderr)
    return code


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


def _terminate(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)  # unwinds through run_grid, which stops the trainers


def _run(args: argparse.Namespace, runs: list[GridRun], extra: list[str]) -> dict[str, int]:
    if args.backend == "ray" and not args.dry_run:
        from gentlerl.distributed.cluster import ClusterError
        from gentlerl.distributed.sweeps import run_grid_on_ray

        cpus = max(1, round(args.workers * args.cpus_per_run))
        try:
            return run_grid_on_ray(runs, extra, args.address, args.cpus_per_run, cpus)
        except ClusterError as err:
            raise SystemExit(str(err)) from None
    return run_grid(runs, args.workers, extra, args.dry_run)


def build_parser(prog: str = "gentlerl sweep") -> argparse.ArgumentParser:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("sweep", help="a wandb grid sweep YAML (recipes/sweeps/*.yaml)")
    parser.add_argument("--out", default="runs/sweeps", help="root folder of the run directories")
    parser.add_argument("--workers", type=int, default=1, help="runs in parallel")
    parser.add_argument(
        "--scale", default=None, choices=("cpu", "paper"), help="added to every run as scale=..."
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        help="extra override, e.g. collector.total_frames=30000",
    )
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        help="run part of the grid: KEY=V1,V2 keeps those values of a swept KEY (repeatable)",
    )
    parser.add_argument("--dry-run", action="store_true", help="print the commands only")
    parser.add_argument(
        "--figures", default=None, help="afterwards, write the paper-style figures here"
    )
    parser.add_argument(
        "--backend", choices=("local", "ray"), default="local",
        help="local: --workers processes here; ray: one Ray task per run (docs/DISTRIBUTED.md)",
    )  # fmt: skip
    parser.add_argument(
        "--address", default=None, help="ray: 'auto', host:port or ray://host:port (default: "
        "a local Ray with --workers x --cpus-per-run CPUs)",
    )  # fmt: skip
    parser.add_argument("--cpus-per-run", type=float, default=1.0, help="ray: CPUs per run")
    return parser


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl sweep") -> int:
    """Run a sweep file's grid (and, with ``--figures``, plot it); 1 if any run failed."""
    args = build_parser(prog).parse_args(argv)
    if args.workers < 1:
        raise SystemExit(f"--workers must be >= 1, got {args.workers}")
    root = Path(args.out) / Path(args.sweep).stem
    try:
        check_set(args.set)
        runs = expand(restrict(load_sweep(args.sweep), args.only), root)
    except (ValueError, OSError) as err:
        raise SystemExit(f"{prog}: {err}") from None
    for run in runs:  # every point's config, before any point runs
        problem = point_problem(run.overrides, args.set, args.scale)
        if problem:
            raise SystemExit(f"{prog}: grid point {run.run_dir.name}: {problem}")
    extra = ([f"scale={args.scale}"] if args.scale else []) + list(args.set)
    handlers = {sig: signal.signal(sig, _terminate) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        counts = _run(args, runs, extra)
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    print(f"{len(runs)} runs: {counts}")
    if args.figures and not args.dry_run:
        from gentlerl.figures import main as plot

        plot([str(root), "-o", args.figures])
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    raise SystemExit(main(prog="python -m gentlerl.sweeps"))
