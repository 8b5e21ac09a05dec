"""Run a wandb sweep file's grid, locally or on Ray, without a wandb server.

    gentlerl sweep recipes/sweeps/fig4_touch.yaml --workers 2 --out runs/sweeps --figures figs

Each grid point becomes one ``gentlerl-train key=value ...`` process with a deterministic
``run_dir`` (``OUT/<sweep>/<key-value_...>``, :mod:`gentlerl.apps.grid`). The runner is
resumable: a run whose ``DONE`` marker exists is skipped, the others run with ``resume=auto``
(continued from their checkpoint, or started again if interrupted before their first). Grid points
that differ only in ``lam_prime`` for a variant without penalty surprise are run once (the
parameter does not affect them). Keys and values are checked before anything runs
(:mod:`gentlerl.apps.sweep_files`), and each point's config is validated; an interrupted sweep
kills its trainers' process groups. The same files work with ``wandb sweep`` / ``wandb agent``.
The points run on a backend (:data:`BACKENDS`): ``local`` runs ``--workers`` at a time here,
``ray`` runs each as a Ray task, on a local Ray or a cluster (:mod:`gentlerl.apps.grid_ray`;
``--out`` on a filesystem every node sees at the same path).
"""

from __future__ import annotations

import argparse
import re
import signal
from collections.abc import Callable, Sequence
from pathlib import Path

from gentlerl.apps.grid import GridRun, expand, restrict, run_grid
from gentlerl.apps.parsing import command_parser
from gentlerl.apps.sweep_files import ALLOW_RAY_FLAG, load_sweep, parse_set, point_problem

#: Runs a grid's points with the extra overrides and the command line's options; the counts of
#: ``done`` / ``skipped`` / ``failed`` / ``planned`` points.
Backend = Callable[[Sequence[GridRun], Sequence[str], argparse.Namespace], dict[str, int]]


def _local(
    runs: Sequence[GridRun], extra: Sequence[str], args: argparse.Namespace
) -> dict[str, int]:
    return run_grid(runs, args.workers, extra, args.dry_run)


def _ray(runs: Sequence[GridRun], extra: Sequence[str], args: argparse.Namespace) -> dict[str, int]:
    if args.dry_run:
        return _local(runs, extra, args)
    from gentlerl.apps.grid_ray import run_grid_on_ray
    from gentlerl.distributed.cluster import ClusterError

    cpus = max(1, round(args.workers * args.cpus_per_run))
    try:
        return run_grid_on_ray(runs, extra, args.address, args.cpus_per_run, cpus)
    except ClusterError as err:
        raise SystemExit(str(err)) from None


#: ``--backend`` name -> how the grid runs.
BACKENDS: dict[str, Backend] = {"local": _local, "ray": _ray}


def _terminate(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)  # unwinds through run_grid, which stops the trainers


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
        "--backend", choices=tuple(BACKENDS), default="local",
        help="local: --workers processes here; ray: one Ray task per run",
    )  # fmt: skip
    parser.add_argument(
        "--address", default=None, help="ray: 'auto', host:port or ray://host:port (default: "
        "a local Ray with --workers x --cpus-per-run CPUs)",
    )  # fmt: skip
    parser.add_argument("--cpus-per-run", type=float, default=1.0, help="ray: CPUs per run")
    parser.add_argument(
        ALLOW_RAY_FLAG, action="store_true",
        help="let the sweep file and --set use collector.kind=ray and collector.ray_address "
        "(the runs' code then executes on that Ray cluster)",
    )  # fmt: skip
    return parser


def _option_problem(args: argparse.Namespace) -> str | None:
    """Why ``--workers``, ``--cpus-per-run`` or ``--address`` cannot be used, or ``None``."""
    from gentlerl.distributed.cluster import parse_address

    if args.workers < 1:
        return f"--workers={args.workers} must be >= 1"
    if not args.cpus_per_run > 0:
        return f"--cpus-per-run={args.cpus_per_run} must be > 0"
    if args.address not in (None, "auto"):
        try:
            parse_address(args.address)
        except ValueError as err:
            return f"--address {err}"
    return None


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl sweep") -> int:
    """Run a sweep file's grid (and, with ``--figures``, plot it); 1 if any run failed."""
    args = build_parser(prog).parse_args(argv)
    problem = _option_problem(args)
    if problem:
        raise SystemExit(f"{prog}: {problem}")
    stem = Path(args.sweep).stem
    if not re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*", stem):
        raise SystemExit(
            f"{prog}: the sweep file's name {stem!r} cannot name its folder under --out (letters, "
            "digits, '_', '-' and '.', not first)"
        )
    root = Path(args.out) / stem
    try:
        extra_items = parse_set(args.set, args.allow_ray_collector)
        grid = load_sweep(args.sweep, args.allow_ray_collector)
        runs = expand(restrict(grid, args.only), root)
    except (ValueError, OSError) as err:
        raise SystemExit(f"{prog}: {err}") from None
    for run in runs:  # every point's config, before any point runs
        problem = point_problem(run.overrides, extra_items, args.scale)
        if problem:
            raise SystemExit(f"{prog}: grid point {run.run_dir.name}: {problem}")
    extra = ([f"scale={args.scale}"] if args.scale else []) + list(args.set)
    handlers = {sig: signal.signal(sig, _terminate) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        counts = BACKENDS[args.backend](runs, extra, args)
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    print(f"{len(runs)} runs: {counts}")
    if args.figures and not args.dry_run:
        from gentlerl.apps.plot import main as plot

        plot([str(root), "-o", args.figures])
    return 1 if counts["failed"] else 0
