"""Run a wandb sweep file's grid locally, without a wandb server.

    gentlerl sweep recipes/sweeps/fig4_touch.yaml --workers 2 --out runs/sweeps --figures figs

Each grid point becomes one ``python -m gentlerl.training.cli key=value ...`` process with a
deterministic ``run_dir`` (``OUT/<sweep>/<key-value_...>``). The runner is resumable: a run whose
``DONE`` marker exists is skipped, one with a checkpoint is continued (``resume=true``). Grid points
that differ only in ``lam_prime`` for a variant without penalty surprise are run once (the
parameter does not affect them). The same files work with ``wandb sweep`` / ``wandb agent``.
``--backend ray`` runs each grid point as a Ray task instead, on a local Ray or a cluster
(:mod:`gentlerl.distributed.sweeps`, docs/DISTRIBUTED.md).
"""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gentlerl.cli import command_parser
from gentlerl.sweep_files import check_set, load_sweep
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
    """Run (or, ``dry_run``, print) the grid; counts ``done``/``skipped``/``failed``/``planned``."""
    todo = pending(runs)
    counts = {"skipped": len(runs) - len(todo), "done": 0, "failed": 0, "planned": 0}
    with ThreadPoolExecutor(max_workers=max(workers, 1)) as pool:
        for code in pool.map(lambda run: run_point(run, extra, dry_run), todo):
            counts["planned" if dry_run else "done" if code == 0 else "failed"] += 1
    return counts


def pending(runs: Sequence[GridRun]) -> list[GridRun]:
    """The runs without a ``DONE`` marker."""
    return [r for r in runs if not (r.run_dir / DONE_MARKER).exists()]


def run_point(run: GridRun, extra: Sequence[str] = (), dry_run: bool = False) -> int:
    """Run one grid point (``resume=true`` if it has a checkpoint); the recipe's exit code.

    Output goes to ``run_dir/stdout.log``. The Ray backend calls this on the worker node.
    """
    resume = ["resume=true"] if (run.run_dir / "checkpoint.pt").exists() else []
    command = run.command([*extra, *resume])
    print(" ".join(command), flush=True)
    if dry_run:
        return 0
    run.run_dir.mkdir(parents=True, exist_ok=True)
    with (run.run_dir / "stdout.log").open("a") as log:
        # subprocess.call kills the recipe when interrupted (Ctrl-C, a cancelled Ray task).
        return subprocess.call(command, stdout=log, stderr=subprocess.STDOUT)


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
    extra = ([f"scale={args.scale}"] if args.scale else []) + list(args.set)
    if args.backend == "ray" and not args.dry_run:
        from gentlerl.distributed.cluster import ClusterError
        from gentlerl.distributed.sweeps import run_grid_on_ray

        cpus = max(1, round(args.workers * args.cpus_per_run))
        try:
            counts = run_grid_on_ray(runs, extra, args.address, args.cpus_per_run, cpus)
        except ClusterError as err:
            raise SystemExit(str(err)) from None
    else:
        counts = run_grid(runs, args.workers, extra, args.dry_run)
    print(f"{len(runs)} runs: {counts}")
    if args.figures and not args.dry_run:
        from gentlerl.figures import main as plot

        plot([str(root), "-o", args.figures])
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    raise SystemExit(main(prog="python -m gentlerl.sweeps"))
