"""Ship trained policies: ``gentlerl export RUNS... --out docs/policies``.

Writes each run's final actor (its ``checkpoint.pt``) as a small policy file
(:func:`gentlerl.training.checkpoint.export_policy`: config and actor weights; no replay buffer,
critics or models) to ``OUT/<task>/<variant>/seed<k>.pt``. Penalty-surprise (``rsp``) variants are
exported at their task's primary lambda'_2 (:data:`gentlerl.analysis.runs.PRIMARY_LAM2`, the value
the claims' criteria judge) and skipped at the others, unless ``--all-lambdas``, which
writes those to ``OUT/<task>/<variant>@lam<lambda'_2>/seed<k>.pt``. Evaluate a shipped policy with
``gentlerl evaluate OUT/touch/r+rf+rsp/seed0.pt --episodes 20``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from gentlerl.analysis.runs import PRIMARY_LAM2, run_task
from gentlerl.apps.parsing import command_parser
from gentlerl.config.layout import CHECKPOINT


def policy_path(config: dict, out: str | os.PathLike, all_lambdas: bool = False) -> Path | None:
    """Where the policy of a run with ``config`` (a ``config.yaml`` / ``TrainConfig.to_dict()``)
    goes under ``out``; ``None`` for an ``rsp`` run at another lambda'_2 than its task's primary
    one (without ``all_lambdas``)."""
    task, variant, seed = config["task"], config["variant"], int(config["seed"])
    folder = variant
    if "rsp" in variant:
        lam2 = float(config["gentleness"]["lam_prime"][1])
        if lam2 != PRIMARY_LAM2.get(task):
            if not all_lambdas:
                return None
            folder = f"{variant}@lam{lam2:g}"
    return Path(out) / task / folder / f"seed{seed}.pt"


def find_checkpoints(paths: Iterable[str | os.PathLike]) -> list[Path]:
    """Every run's ``checkpoint.pt`` under ``paths`` (each a checkpoint, a run or a folder)."""
    found: list[Path] = []
    for path in map(Path, paths):
        if not path.exists():
            raise FileNotFoundError(f"no such file or run directory: {path}")
        found += [path] if path.is_file() else sorted(path.rglob(CHECKPOINT))
    if not found:
        raise FileNotFoundError(f"no {CHECKPOINT} under {[str(p) for p in paths]}")
    return found


def export_runs(
    paths: Iterable[str | os.PathLike],
    out: str | os.PathLike,
    *,
    tasks: Sequence[str] = ("touch", "fragile"),
    all_lambdas: bool = False,
) -> dict[Path, Path]:
    """Export the final actor of every run under ``paths`` whose task is in ``tasks`` (see the
    module docstring); returns ``{policy file: checkpoint}``. Two runs that would write the same
    file are an error naming both."""
    from gentlerl.training.checkpoint import load_checkpoint, policy_file_state, save_checkpoint

    written: dict[Path, Path] = {}
    for ckpt in find_checkpoints(paths):
        policy = policy_file_state(load_checkpoint(ckpt), ckpt)
        dest = policy_path(policy["config"], out, all_lambdas)
        if run_task(policy["config"]) not in tasks or dest is None:  # external envs: skipped
            continue
        if dest in written:
            raise ValueError(f"{written[dest]} and {ckpt} would both be exported to {dest}")
        save_checkpoint(dest, policy)
        written[dest] = ckpt
    return written


def export_suite_runs(
    out: str | os.PathLike, to: str | os.PathLike, tasks: Sequence[str] = ("touch", "fragile")
) -> dict[Path, Path]:
    """The final actor of every finished (``DONE``) run of ``tasks`` in a suite's folder ``out``,
    to ``to/<task>/<cell's variant>/seed<k>.pt``: the folder names of the suite's cells (a
    steered cell's ``constrained``, not its config's ``r+rf``), every lambda'_2 as the suite
    declared it; returns ``{policy file: checkpoint}``."""
    from gentlerl.config.layout import RunLayout
    from gentlerl.training.checkpoint import load_checkpoint, policy_file_state, save_checkpoint

    out, written = Path(out), {}
    for ckpt in find_checkpoints([out]):
        if not RunLayout(ckpt.parent).done.exists():
            continue
        policy = policy_file_state(load_checkpoint(ckpt), ckpt)
        if run_task(policy["config"]) not in tasks:  # external envs: skipped
            continue
        run = ckpt.parent.relative_to(out)
        dest = Path(to) / run.parent / f"{run.name}.pt"
        save_checkpoint(dest, policy)
        written[dest] = ckpt
    return written


def export_and_list(out: str | os.PathLike, to: str | os.PathLike) -> None:
    """The final actor of every finished hand run of a suite's folder ``out`` (``gentlerl suite
    run --export``, :func:`export_suite_runs`), each file printed with its checkpoint."""
    written = export_suite_runs(out, to)
    for dest, ckpt in sorted(written.items()):
        print(f"{dest} <- {ckpt}")
    print(
        f"{len(written)} policies under {to}" if written else f"no hand run under {out} to export"
    )


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl export") -> None:
    """Export the runs named on the command line; print each file with its size."""
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="checkpoint.pt files, run folders or sweep folders")
    parser.add_argument(
        "--out", default="docs/policies", help="root of <task>/<variant>/seed<k>.pt"
    )
    parser.add_argument(
        "--tasks",
        nargs="+",
        default=["touch", "fragile"],
        choices=list(PRIMARY_LAM2),
        help="export runs of these tasks",
    )
    parser.add_argument(
        "--all-lambdas", action="store_true", help="also rsp runs at non-primary lambda'_2 values"
    )
    args = parser.parse_args(argv)
    written = export_runs(args.runs, args.out, tasks=args.tasks, all_lambdas=args.all_lambdas)
    if not written:
        raise FileNotFoundError(f"no run of tasks {args.tasks} to export under {args.runs}")
    for dest, ckpt in sorted(written.items()):
        print(f"{dest} ({dest.stat().st_size / 1024:.0f} KiB) <- {ckpt}")
    print(f"{len(written)} policies under {args.out}")
