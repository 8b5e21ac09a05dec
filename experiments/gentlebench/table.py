"""GentleBench's table with its verdicts (:mod:`experiments.gentlebench.criteria`).

    python experiments/gentlebench/table.py runs/gentlebench

Reads each run's ``final_eval_episodes.csv`` and ``config.yaml`` under
``ROOT/gentlebench_<task>/<run>/`` (what ``experiments/gentlebench/grid.sh`` writes) and prints a
markdown table, each variant judged against ``r`` on its task.
"""

from __future__ import annotations

import csv
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

from gentlerl.files import load_yaml_file, open_checked

if __package__ in (None, ""):  # run as a script: the checkout's root on the path, as in the tests
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from experiments.gentlebench.criteria import gentlebench_verdict  # noqa: E402
from experiments.table_cli import main  # noqa: E402

GENTLEBENCH_VARIANTS = ("r", "r+rf", "r+rf+rsp")


def load_gentlebench(root: Path) -> dict[str, dict[str, list[dict]]]:
    """task -> variant -> per seed (in seed order): ``returns`` and ``impacts`` (N, the rewards'
    ``env.force_scale`` undone) of its final actor's episodes."""
    out: dict[str, dict[str, list[dict]]] = {}
    for episodes in sorted(root.glob("gentlebench_*/*/final_eval_episodes.csv")):
        config = load_yaml_file(episodes.parent / "config.yaml")
        scale = float(config["env"]["force_scale"])
        with open_checked(episodes, newline="") as f:
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


if __name__ == "__main__":
    main(gentlebench_table, __doc__.splitlines()[0], "experiments/gentlebench/table.py")
