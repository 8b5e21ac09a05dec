"""GentleBench's table and verdicts (docs/GENTLEBENCH.md's pre-registered criteria), from each
run's ``final_eval_episodes.csv`` (``recipes/gentlebench.sh``):

    python recipes/gentlebench_table.py runs/gentlebench

Per task and variant: the per-seed mean return of the final actor's episodes, their median over
seeds, the median / p90 per-episode max impact over all episodes in N (the rewards read the force
times ``env.force_scale``; that factor is undone here), the share of episodes touching, and the
verdict against ``r`` on the same task.
"""

from __future__ import annotations

import csv
import statistics
import sys
from pathlib import Path

import numpy as np
import yaml

VARIANTS = ("r", "r+rf", "r+rf+rsp")
#: Below this median return ``r`` has not learned the task (2 % of dm_control's 1000 ceiling).
R_LEARNS = 20.0


def load(root: Path) -> dict[str, dict[str, list[dict]]]:
    """task -> variant -> per seed (in seed order): ``returns`` and ``impacts`` (N) of its episodes."""
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
    for variants in out.values():
        for seeds in variants.values():
            seeds.sort(key=lambda s: s["seed"])
    return out


def row(seeds: list[dict]) -> dict:
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


def verdict(r: dict, other: dict) -> str:
    """docs/GENTLEBENCH.md's labels for one variant against ``r`` on the same task."""
    gentler = other["median_impact"] <= 0.5 * r["median_impact"]
    if r["median_return"] < R_LEARNS:
        return "not judged: r does not learn at 30k" + ("; gentler" if gentler else "")
    keeps = other["median_return"] >= 0.8 * r["median_return"]
    return {
        (True, True): "gentle and as good",
        (False, True): "gentle but worse",
        (True, False): "no gentleness gain",
        (False, False): "neither",
    }[(keeps, gentler)]


def main(argv: list[str]) -> None:
    if len(argv) != 1:
        raise SystemExit("usage: python recipes/gentlebench_table.py RUNS_DIR")
    runs = load(Path(argv[0]))
    print(
        "| task | variant | return per seed (mean of its episodes) | median return | "
        "max impact per episode, median / p90 (N) | episodes touching | verdict vs `r` |"
    )
    print("| --- | --- | --- | ---: | --- | ---: | --- |")
    for task, variants in sorted(runs.items()):
        rows = {v: row(variants[v]) for v in VARIANTS if v in variants}
        for variant, r in rows.items():
            judged = "" if variant == "r" or "r" not in rows else verdict(rows["r"], r)
            print(
                f"| {task} | `{variant}` | {' / '.join(f'{x:.1f}' for x in r['returns'])} | "
                f"{r['median_return']:.1f} | {r['median_impact']:.1f} / {r['p90_impact']:.1f} | "
                f"{r['touching']:.0%} | {judged} |"
            )


if __name__ == "__main__":
    main(sys.argv[1:])
