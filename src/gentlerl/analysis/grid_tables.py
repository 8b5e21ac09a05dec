"""The tables of two pre-registered grids, with their verdicts (:mod:`gentlerl.analysis.criteria`).

- the SAC grid (docs/SAC.md, ``recipes/grids/sac_grid.sh``): each run's ``final_eval.json`` under
  ``ROOT/<task>/<variant>/seed<k>/`` (:func:`sac_table`);
- GentleBench (docs/GENTLEBENCH.md, ``recipes/grids/gentlebench.sh``): each run's
  ``final_eval_episodes.csv`` and ``config.yaml`` under ``ROOT/gentlebench_<task>/<run>/``
  (:func:`gentlebench_table`).

Each returns a markdown table; ``gentlerl table`` prints it (:mod:`gentlerl.apps.table`).
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gentlerl.analysis.criteria import gentlebench_verdict, sac_verdict

SAC_VARIANTS = ("r", "r+rf+rsp")
GENTLEBENCH_VARIANTS = ("r", "r+rf", "r+rf+rsp")


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


def load_gentlebench(root: Path) -> dict[str, dict[str, list[dict]]]:
    """task -> variant -> per seed (in seed order): ``returns`` and ``impacts`` (N, the rewards'
    ``env.force_scale`` undone) of its final actor's episodes."""
    out: dict[str, dict[str, list[dict]]] = {}
    for episodes in sorted(root.glob("gentlebench_*/*/final_eval_episodes.csv")):
        config = yaml.safe_load((episodes.parent / "config.yaml").read_text())
        scale = float(config["env"]["force_scale"])
        with episodes.open() as f:
            rows = list(csv.DictReader(f))
        seed = {
            "seed": int(config["seed"]),
            "returns": np.array([float(r["return"]) for r in rows]),
            "impacts": np.array([float(r["max_impact"]) for r in rows]) / scale,
        }
        task = config["env"]["name"].split(":", 1)[1]
        out.setdefault(task, {}).setdefault(config["variant"], []).append(seed)
    if not out:
        raise FileNotFoundError(f"no gentlebench_<task>/<run>/final_eval_episodes.csv under {root}")
    for variants in out.values():
        for seeds in variants.values():
            seeds.sort(key=lambda s: s["seed"])
    return out


def gentlebench_row(seeds: list[dict]) -> dict[str, Any]:
    """One (task, variant) row: per-seed mean return and their median, the median / p90
    per-episode max impact over all episodes (N) and the share of episodes touching."""
    impacts = np.concatenate([s["impacts"] for s in seeds])
    means = [float(s["returns"].mean()) for s in seeds]
    return {
        "seeds": len(seeds),
        "returns": means,
        "median_return": statistics.median(means),
        "median_impact": float(np.median(impacts)),
        "p90_impact": float(np.percentile(impacts, 90)),
        "touching": float((impacts > 0).mean()),
    }


def gentlebench_table(root: Path) -> str:
    """GentleBench's markdown table, each variant judged against ``r`` on its task
    (:func:`gentlebench_verdict`)."""
    lines = [
        "| task | variant | return per seed (mean of its episodes) | median return | "
        "max impact per episode, median / p90 (N) | episodes touching | verdict vs `r` |",
        "| --- | --- | --- | ---: | --- | ---: | --- |",
    ]
    for task, variants in sorted(load_gentlebench(root).items()):
        rows = {v: gentlebench_row(variants[v]) for v in GENTLEBENCH_VARIANTS if v in variants}
        for variant, r in rows.items():
            judged = "" if variant == "r" or "r" not in rows else gentlebench_verdict(rows["r"], r)
            lines.append(
                f"| {task} | `{variant}` | {' / '.join(f'{x:.1f}' for x in r['returns'])} | "
                f"{r['median_return']:.1f} | {r['median_impact']:.1f} / {r['p90_impact']:.1f} | "
                f"{r['touching']:.0%} | {judged} |"
            )
    return "\n".join(lines) + "\n"
