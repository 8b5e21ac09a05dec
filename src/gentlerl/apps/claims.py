"""The paper's six claims judged by their pre-registered criteria (:mod:`gentlerl.analysis.criteria`).

    gentlerl claims [NAME=]RUNS_ROOT ... [--final-evals DIR] [--seeds 0,1] [--markdown OUT.md]

``RUNS_ROOT`` holds the three sweeps of ``recipes/grids/reproduce.sh`` (``fig3_noreward_impacts``,
``fig4_touch``, ``fig4_fragile``, each a folder of run directories). "Final success" is the
success rate of each run's last actor over the 20 episodes of ``gentlerl evaluate
checkpoint.pt --episodes 20 --seed 0 --json`` that ``reproduce.sh`` writes to
``DIR/<sweep>/final_eval.jsonl``, averaged over seeds; without that file a run's last in-loop
evaluation is used and the report says so. Impacts of the successful final-policy rollouts
(claim 5, :func:`gentlerl.analysis.runs.successful_final_impacts`) come from the same 20 episodes
(``final_eval_episodes.csv`` next to each checkpoint, written by ``reproduce.sh``), else from
the run's last in-loop evaluation (``eval_episodes.csv``). Rollouts "after the switch" are the
training rollouts logged after :func:`gentlerl.analysis.runs.intrinsic_start`; "touching" means
max impact > 0. The criteria themselves are :mod:`gentlerl.analysis.criteria`, the reading and formatting
:mod:`gentlerl.analysis.claims`.

A verdict is ``reproduced`` when every condition of the claim holds, ``partly`` when its weaker
condition holds, otherwise ``not reproduced``; a claim whose runs are missing is ``no data``.

Several roots (the rows of an ablation, e.g. ``changes=runs/cpu/changes
no-nll-floor=runs/cpu/no-nll-floor``) give one verdict column per root, then each root's table;
``--seeds`` judges only the runs of those seeds, so that rows with different seed counts can be
compared on the seeds they share.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from gentlerl.analysis.claims import (
    format_comparison,
    format_verdicts,
    group_by_variant,
    load_final_evals,
)
from gentlerl.analysis.criteria import Verdict, judge
from gentlerl.analysis.runs import find_runs
from gentlerl.files import write_atomic


def _row(spec: str) -> tuple[str, Path]:
    name, sep, path = spec.rpartition("=")
    return (name if sep else spec), Path(path)


def _seeds(text: str) -> set[int]:
    try:
        return {int(s) for s in text.split(",")}
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seeds takes integers like 0,1; got {text!r}") from None


def _judge_root(
    root: Path, evals: dict[str, float], seeds: set[int] | None
) -> tuple[list[Verdict], int]:
    runs = [r for r in find_runs([root]) if seeds is None or int(r.config["seed"]) in seeds]
    if not runs:
        raise FileNotFoundError(f"no runs of seeds {sorted(seeds or ())} under {root}")
    return judge(group_by_variant(runs), evals), len(runs)


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl claims") -> None:
    """Print (and with ``--markdown``, write) the verdict table of one or several grids."""
    parser = argparse.ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "runs",
        nargs="+",
        type=_row,
        help="[NAME=]the --out/<scale>/<method> folder of reproduce.sh",
    )
    parser.add_argument("--final-evals", type=Path, help="folder with <sweep>/final_eval.jsonl")
    parser.add_argument("--seeds", type=_seeds, help="judge only these seeds, e.g. 0,1")
    parser.add_argument("--markdown", type=Path, help="also write the table to this file")
    args = parser.parse_args(argv)
    evals = load_final_evals(args.final_evals) if args.final_evals else {}
    source = "final_eval.jsonl (20 episodes)" if evals else "each run's last in-loop evaluation"
    seeds = f" (seeds {','.join(map(str, sorted(args.seeds)))})" if args.seeds else ""
    rows, tables = {}, []
    for name, root in args.runs:
        rows[name], n = _judge_root(root, evals, args.seeds)
        tables.append(
            f"{format_verdicts(rows[name])}\n{n} runs{seeds} under {root}; final success from "
            f"{source}.\n"
        )
    table = tables[0]
    if len(rows) > 1:
        table = format_comparison(rows) + "".join(
            f"\n### {name}\n\n{t}" for name, t in zip(rows, tables, strict=True)
        )
    print(table, end="")
    if args.markdown:
        write_atomic(args.markdown, table)
