"""The SAC grid's table and verdicts (docs/SAC.md's pre-registered criteria), from the runs'
``final_eval.json``: ``python recipes/sac_table.py runs/sac``."""

from __future__ import annotations

import json
import math
import statistics
import sys
from pathlib import Path

VARIANTS = ("r", "r+rf+rsp")


def load(root: Path) -> dict[tuple[str, str], list[dict]]:
    """(task, variant) -> the final evaluations of its seeds, in seed order."""
    runs: dict[tuple[str, str], list[dict]] = {}
    for path in sorted(root.glob("*/*/seed*/final_eval.json")):
        task, variant = path.parts[-4], path.parts[-3]
        runs.setdefault((task, variant), []).append(json.loads(path.read_text()))
    return runs


def row(evals: list[dict]) -> dict[str, float]:
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


def verdict(task: str, r: dict, rsp: dict) -> str:
    """docs/SAC.md's rule for one task."""
    if r["mean_success"] < 0.5 and rsp["mean_success"] < 0.5:
        return "SAC does not learn the task at this budget"
    success = rsp["mean_success"] >= max(0.8 * r["mean_success"], 0.5)
    if math.isnan(r["successful_impact"]):  # added after the first runs: r never succeeded
        return (
            "more successful than r, which never succeeds; impacts not comparable"
            if success
            else "neither variant succeeds often enough to compare impacts"
        )
    impact = rsp["successful_impact"] <= 0.75 * r["successful_impact"]
    words = (
        "gentleness transfers"
        if success and impact
        else "gentler but less successful"
        if impact
        else "not gentler"
    )
    if task == "fragile" and rsp["mean_success"] >= r["mean_success"] + 0.3:
        words += "; helps on the fragile block"
    return words


def main(root: str) -> None:
    runs = load(Path(root))
    print(
        "| task | variant | seeds | final success per seed | mean | broken | median / p90 max "
        "impact (N) | median max impact of successful episodes (N) |"
    )
    print("| --- | --- | ---: | --- | ---: | ---: | --- | ---: |")
    rows = {}
    for (task, variant), evals in sorted(runs.items()):
        rows[task, variant] = r = row(evals)
        per_seed = " / ".join(f"{s:.2f}" for s in r["success"])
        print(
            f"| {task} | `{variant}` | {r['seeds']} | {per_seed} | {r['mean_success']:.2f} | "
            f"{r['broken']:.2f} | {r['median_max_impact']:.2f} / {r['p90_max_impact']:.2f} | "
            f"{r['successful_impact']:.2f} |"
        )
    for task in sorted({t for t, _ in rows}):
        if all((task, v) in rows for v in VARIANTS):
            print(f"\n{task}: {verdict(task, rows[task, 'r'], rows[task, 'r+rf+rsp'])}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "runs/sac")
