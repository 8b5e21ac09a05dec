"""The SAC grid's table with its verdicts (:mod:`experiments.sac_grid.criteria`, docs/log/SAC.md).

    python experiments/sac_grid/table.py runs/sac

Reads each run's ``final_eval.json`` under ``ROOT/<task>/<variant>/seed<k>/`` (what
``experiments/sac_grid/grid.sh`` writes) and prints a markdown table, then each task's verdict.
"""

from __future__ import annotations

import json
import math
import statistics
import sys
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: the checkout's root on the path, as in the tests
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from experiments.sac_grid.criteria import sac_verdict  # noqa: E402
from experiments.table_cli import main  # noqa: E402

SAC_VARIANTS = ("r", "r+rf+rsp")


def load_sac_grid(root: Path) -> dict[tuple[str, str], list[dict]]:
    """(task, variant) -> the final evaluations of its seeds, in seed order."""
    runs: dict[tuple[str, str], list[dict]] = {}
    for path in sorted(root.glob("*/*/seed*/final_eval.json")):
        task, variant = path.parts[-4], path.parts[-3]
        runs.setdefault((task, variant), []).append(json.loads(path.read_text()))
    if not runs:
        raise FileNotFoundError(f"no <task>/<variant>/seed<k>/final_eval.json under {root}")
    return runs


def sac_row(evals: list[dict]) -> dict[str, Any]:
    """One (task, variant) row: success per seed and its mean, the mean broken rate, and the
    medians over seeds of the median / p90 max impact and of the successful episodes' one."""

    def median(key: str) -> float:
        values = [e[key] for e in evals if not math.isnan(e[key])]
        return statistics.median(values) if values else math.nan

    return {
        "seeds": len(evals),
        "success": [e["success_rate"] for e in evals],
        "mean_success": statistics.mean(e["success_rate"] for e in evals),
        "broken": statistics.mean(e["broken_rate"] for e in evals),
        "median_max_impact": median("median_max_impact"),
        "p90_max_impact": median("p90_max_impact"),
        "successful_impact": median("median_max_impact_successful"),
    }


def sac_table(root: Path) -> str:
    """The SAC grid's markdown table, then each task's verdict (:func:`sac_verdict`)."""
    lines = [
        "| task | variant | seeds | final success per seed | mean | broken | median / p90 max "
        "impact (N) | median max impact of successful episodes (N) |",
        "| --- | --- | ---: | --- | ---: | ---: | --- | ---: |",
    ]
    rows = {key: sac_row(evals) for key, evals in sorted(load_sac_grid(root).items())}
    for (task, variant), r in rows.items():
        per_seed = " / ".join(f"{s:.2f}" for s in r["success"])
        lines.append(
            f"| {task} | `{variant}` | {r['seeds']} | {per_seed} | {r['mean_success']:.2f} | "
            f"{r['broken']:.2f} | {r['median_max_impact']:.2f} / {r['p90_max_impact']:.2f} | "
            f"{r['successful_impact']:.2f} |"
        )
    for task in sorted({t for t, _ in rows}):
        if all((task, v) in rows for v in SAC_VARIANTS):
            verdict = sac_verdict(task, rows[task, "r"], rows[task, "r+rf+rsp"])
            lines.append(f"\n{task}: {verdict}")
        for new in ("new", "new_w1"):  # Method III's rows, judged alike
            if (task, "r") in rows and (task, new) in rows:
                verdict = sac_verdict(task, rows[task, "r"], rows[task, new])
                lines.append(f"\n{task}, {new}: {verdict}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(sac_table, __doc__.splitlines()[0], "experiments/sac_grid/table.py")
