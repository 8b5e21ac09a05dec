"""Run a declared benchmark suite: each cell's seeds trained, one results file (``suite run``).

    gentlerl suite run experiments/suites/after_fix.yaml --out runs/after_fix
    gentlerl table runs/after_fix/results.csv --out runs/after_fix/table.md
    gentlerl suite run experiments/suites/after_fix.yaml --out runs/after_fix \
        --cells 'touch/*' --cells 'fragile/*' --export docs/policies/after_fix

A suite file (:mod:`gentlerl.apps.suite_files`) declares tasks x variants x seeds at a budget.
Every cell's configs are checked before any folder is made (each refusal one line, all of them
at once). Then each cell trains in ``DIR/<task>/<variant>/seed<k>``: its seeds as one seed group
(:func:`~gentlerl.training.seed_group.train_seeds`), or, for a steered cell
(``gentleness.multiplier``, which a group does not batch), one seed after the other in this
process. A cell whose runs are all ``DONE`` is not run again, so the command can be rerun until
the suite is finished; a seed group does not resume, so a cell interrupted after its seeds' first
checkpoint is refused until its folder is removed. After each cell, ``DIR/results.csv`` is
rewritten whole (:mod:`gentlerl.analysis.results`: one row per run, its final evaluation, wall
clock, the code's version and commit, the date), and a line says how the cell did. ``--export
DIR`` then writes every finished hand run's final actor to ``DIR/<task>/<variant>/seed<k>.pt``
(:func:`gentlerl.apps.export.export_suite_runs`): the shipped policies from one command.
"""

from __future__ import annotations

import fnmatch
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gentlerl.apps.parsing import command_parser
from gentlerl.apps.suite_files import Cell, Suite, load_suite
from gentlerl.config.layout import RunLayout

if TYPE_CHECKING:
    from gentlerl.training.config import TrainConfig

#: The results file under ``--out``.
RESULTS = "results.csv"


class SuiteRefused(ValueError):
    """A suite that cannot run: :attr:`problems`, one line each."""

    def __init__(self, problems: Sequence[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = list(problems)


@dataclass(frozen=True)
class PlannedCell:
    """A cell ready to run: its seeds' validated configs, how they train, whether all are done."""

    cell: Cell
    cfgs: tuple[TrainConfig, ...]
    grouped: bool
    done: bool


def _line(err: BaseException) -> str:
    """A config refusal's lines as one line (the first is its heading when several follow)."""
    lines = [line.strip().removeprefix("- ") for line in str(err).splitlines() if line.strip()]
    return "; ".join(lines[1:]) if len(lines) > 1 else (lines or [type(err).__name__])[0]


def _cell_problems(cell: Cell, seeds: Sequence[int], out: Path) -> tuple[PlannedCell | None, list]:
    """The cell's plan, or why it cannot run."""
    from gentlerl.apps.seeds import group_configs

    folder = out / cell.task / cell.variant
    for path in (out / cell.task, folder):
        if path.is_symlink():
            return None, [f"{path} is a symbolic link: nothing is written through one; remove it"]
    try:
        cfgs = tuple(group_configs(seeds, cell.items, folder))
    except (ValueError, TypeError) as err:
        return None, [_line(err)]
    from gentlerl.files import folder_link_problem

    if links := [p for cfg in cfgs if (p := folder_link_problem(cfg.run_dir))]:
        return None, links
    grouped = cfgs[0].gentleness.multiplier == "none"
    done = all(RunLayout(cfg.run_dir).done.exists() for cfg in cfgs)
    planned = PlannedCell(cell, cfgs, grouped, done)
    if done or not grouped:  # a lone run resumes from its checkpoint (resume=auto)
        return planned, []
    if any(RunLayout(cfg.run_dir).checkpoint.exists() for cfg in cfgs):
        return None, [
            f"{folder} holds the checkpoints of an interrupted seed group, which does not resume: "
            "remove the folder to run the cell again"
        ]
    from gentlerl.training.seed_group import group_problems

    problems = group_problems(cfgs)
    return (None, problems) if problems else (planned, [])


def plan_suite(suite: Suite, out: str | Path, patterns: Sequence[str] = ()) -> list[PlannedCell]:
    """Every selected cell (``patterns``: shell patterns of ``task/variant``; none: all) planned,
    or :class:`SuiteRefused` listing every problem; nothing is written."""
    from gentlerl.apps.outputs import check_output_file

    out = Path(out)
    cells = [
        c
        for c in suite.cells
        if not patterns or any(fnmatch.fnmatchcase(c.name, p) for p in patterns)
    ]
    problems = (
        []
        if cells
        else [f"--cells {list(patterns)} matches none of {[c.name for c in suite.cells]}"]
    )
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise SuiteRefused([f"--out {out}: not a folder (or a symbolic link)"])
    try:
        check_output_file(out / RESULTS, (".csv",))
        _existing(out, suite.name)
    except (ValueError, OSError) as err:
        problems.append(str(err))
    planned = []
    for cell in cells:
        plan, found = _cell_problems(cell, suite.seeds, out)
        problems += [f"cell {cell.name}: {p}" for p in found]
        if plan is not None:
            planned.append(plan)
    if problems:
        raise SuiteRefused(problems)
    return planned


def _existing(out: Path, suite: str) -> list[dict[str, Any]]:
    """The rows ``out``'s results file holds (none yet: empty); another suite's are refused."""
    from gentlerl.analysis.results import read_results

    path = out / RESULTS
    rows = read_results(path) if path.is_file() else []
    others = sorted({row["suite"] for row in rows} - {suite})
    if others:
        raise ValueError(
            f"{path} holds the rows of suite {others[0]!r}: give {suite!r} its own --out"
        )
    return rows


def code_version() -> dict[str, str]:
    """``version`` (:data:`gentlerl.__version__`) and ``commit``: the git commit of the checkout
    gentlerl runs from (``+dirty`` when its ``src/`` differs from it), ``unknown`` when it does
    not run from a git checkout's ``src/gentlerl``."""
    import gentlerl

    package = Path(gentlerl.__file__).resolve().parent

    def git(where: Path, *args: str) -> str:
        done = subprocess.run(
            ["git", "-C", str(where), *args], capture_output=True, text=True, timeout=30
        )
        return done.stdout.strip() if done.returncode == 0 else ""

    commit = "unknown"
    try:
        top = git(package, "rev-parse", "--show-toplevel")
        # a package installed into a venv inside some checkout is not that checkout's code
        if top and (Path(top) / "src" / "gentlerl").resolve() == package:
            commit = git(Path(top), "rev-parse", "HEAD") or "unknown"
            changed = git(Path(top), "status", "--porcelain", "--untracked-files=all", "--", "src")
            if commit != "unknown" and changed:
                commit += "+dirty"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    return {"version": gentlerl.__version__, "commit": commit}


def _cell_rows(suite: Suite, plan: PlannedCell, stamp: dict, kept: dict) -> list[dict]:
    """The cell's rows: kept from the results file for a cell not run now, else read from its
    run directories."""
    from gentlerl.analysis.results import run_result

    rows = []
    for cfg in plan.cfgs:
        key = (plan.cell.name, cfg.seed)
        if plan.done and key in kept:
            rows.append(kept[key])
            continue
        where = {"suite": suite.name, "cell": plan.cell.name, "task": plan.cell.task}
        rows.append(
            {**where, "variant": plan.cell.variant, "seed": cfg.seed, **run_result(cfg.run_dir),
             "grouped": int(plan.grouped), **stamp}
        )  # fmt: skip
    return rows


def _summary(rows: Sequence[dict]) -> str:
    from gentlerl.analysis.results_table import format_mean_std

    def cell(column: str) -> str:
        return format_mean_std([row.get(column) for row in rows])

    line = f"return {cell('return')}, max impact {cell('max_impact')} N, success {cell('success_rate')}"
    return line + (
        f", cost {cell('cost')}" if any(row.get("cost") is not None for row in rows) else ""
    )


def _train(plan: PlannedCell, env_factory: Callable | None) -> None:
    if plan.grouped:
        from gentlerl.training.seed_group import train_seeds

        train_seeds(list(plan.cfgs), env_factory)
        return
    from gentlerl.training import train

    for cfg in plan.cfgs:  # a steered run: its own penalty weight, so seed by seed
        train(cfg, env_factory)


def run_suite(
    suite: Suite,
    out: str | Path,
    patterns: Sequence[str] = (),
    *,
    dry_run: bool = False,
    env_factory: Callable | None = None,
    echo: Callable[[str], None] = print,
) -> list[dict[str, Any]]:
    """Plan (:func:`plan_suite`), then train each cell not yet done and rewrite the results file
    after it; the results file's rows (none with ``dry_run``, which only says what would run).
    ``env_factory`` (tests: a toy env) replaces every cell's env, as in
    :func:`~gentlerl.training.loop.train`."""
    from gentlerl.analysis.results import write_results

    out = Path(out)
    plans = plan_suite(suite, out, patterns)
    kept = {(row["cell"], row["seed"]): row for row in _existing(out, suite.name)}
    stamp = {**code_version(), "date": datetime.now(timezone.utc).strftime("%Y-%m-%d")}
    for i, plan in enumerate(plans, 1):
        head = f"[{i}/{len(plans)}] {plan.cell.name}"
        frames = plan.cfgs[0].collector.total_frames
        how = "as one seed group" if plan.grouped else "one by one (steered: gentleness.multiplier)"
        if plan.done:
            echo(f"{head}: finished earlier (DONE), not run again")
        elif dry_run:
            echo(
                f"{head}: would train seeds {list(suite.seeds)} {how}, {frames} frames: {' '.join(plan.cell.items)}"
            )
            continue
        else:
            echo(f"{head}: training seeds {list(suite.seeds)} {how}, {frames} frames ...")
            start = time.perf_counter()
            _train(plan, env_factory)
            echo(f"{head}: trained in {time.perf_counter() - start:.0f} s")
        if dry_run:
            continue
        rows = _cell_rows(suite, plan, stamp, kept)
        kept.update({(row["cell"], row["seed"]): row for row in rows})
        out.mkdir(parents=True, exist_ok=True)
        write_results(out / RESULTS, _ordered(suite, kept))
        echo(f"{head}: {_summary(rows)}")
    return [] if dry_run else _ordered(suite, kept)


def _ordered(suite: Suite, rows: dict) -> list[dict]:
    """The rows in the suite's order (cells, then seeds), then any other cell's as they were."""
    order = [(cell.name, seed) for cell in suite.cells for seed in suite.seeds]
    return [rows[k] for k in order if k in rows] + [v for k, v in rows.items() if k not in order]


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl suite") -> int:
    """``gentlerl suite run``: run a suite file's cells; refusals one line each."""
    parser = command_parser(prog, __doc__.splitlines()[0])
    actions = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    run = actions.add_parser(
        "run", help="train every cell not yet done, then rewrite OUT/results.csv",
        formatter_class=parser.formatter_class,
    )  # fmt: skip
    run.add_argument("suite", metavar="SUITE", help="a suite file (experiments/suites/*.yaml)")
    run.add_argument("--out", required=True, help="the suite's folder: its runs and results.csv")
    run.add_argument(
        "--cells", action="append", default=[], metavar="PATTERN",
        help="only the cells whose task/variant matches this shell pattern (touch/*); repeatable",
    )  # fmt: skip
    run.add_argument("--dry-run", action="store_true", help="check and list the cells only")
    run.add_argument(
        "--export", metavar="DIR",
        help="then write every finished hand run's actor to DIR/<task>/<variant>/seed<k>.pt",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.export and args.dry_run:
        parser.error("--export writes policies; a --dry-run writes nothing: give one of them")
    from gentlerl.apps.train import quiet_torchrl_info

    quiet_torchrl_info()  # before TorchRL is imported
    try:
        suite = load_suite(args.suite)
        rows = run_suite(suite, args.out, args.cells, dry_run=args.dry_run)
    except SuiteRefused as err:
        for problem in err.problems:  # every cell's, each on its line, as the command's errors
            print(f"{prog}: error: {problem}", file=sys.stderr)
        return 1
    if rows:
        results = Path(args.out) / RESULTS
        print(f"{results}: {len(rows)} runs; their table: gentlerl table {results}")
    if args.export:
        from gentlerl.apps.export import export_and_list

        export_and_list(args.out, args.export)
    return 0
