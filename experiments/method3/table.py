"""The Method III grid's table (docs/log/GENTLEBENCH.md, "Method III amendment";
``experiments/method3/grid.sh``): per task, ``r``, the paper's ``r+rf+rsp``, the new method and the
constrained baseline side by side, in the safe-RL benchmarks' form, with the pre-registered tests
(:func:`experiments.method3.criteria.method3_verdicts`).

    python experiments/method3/table.py runs/method3

Reads each run's final actor's episodes (``final_eval_episodes.csv``, written by ``gentlerl
evaluate``), its config, its ``train/penalty_surprise_per_contact_step`` and
``train/penalty_weight`` scalars (:mod:`gentlerl.analysis.runs`); the weight's trajectory is
printed for each task's first seed under the table.
"""

from __future__ import annotations

import csv
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

from gentlerl.analysis.runs import Run, find_runs
from gentlerl.files import open_checked

if __package__ in (None, ""):  # run as a script: the checkout's root on the path, as in the tests
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from experiments.method3.criteria import METHOD3_VARIANTS, method3_verdicts  # noqa: E402
from experiments.table_cli import main  # noqa: E402

#: The frames at the end of a run over which r^sp per contact step is averaged.
LAST_FRAMES = 10_000


def method3_label(run: Run) -> str:
    """``r``, ``r+rf+rsp`` (the paper under the tolerance rule), ``new`` or ``baseline``; or the
    paper's ``r+rf+rsp`` with one of new's two mechanisms: ``norm alone`` (the normalised
    curiosity), ``pid alone`` (the multiplier). A multiplier on the deployed policy's episodes
    (``multiplier_episodes``, the fourth amendment) on ``r+rf+rsp`` is that amendment's ``new``
    (a plain Lagrangian, ``multiplier_base`` 0), or ``new, w0=1`` with the paper's weight as floor."""
    steered = run.setting("gentleness", "multiplier", "none") != "none"
    if "rsp" not in run.variant:
        return "baseline" if steered else run.variant
    if steered and run.setting("gentleness", "multiplier_episodes", 0):  # the fourth amendment
        base = float(run.setting("gentleness", "multiplier_base", 1.0))
        return "new" if base == 0 else f"new, w0={base:g}"
    norm = bool(run.setting("gentleness", "curiosity_norm", False))
    return {(True, True): "new", (True, False): "pid alone", (False, True): "norm alone"}.get(
        (steered, norm), run.variant
    )


def _tail_mean(run: Run, name: str) -> float:
    frames, values = run.scalars.get(name, (np.zeros(0), np.zeros(0)))
    if not len(frames):
        return float("nan")
    return float(values[frames >= frames[-1] - LAST_FRAMES].mean())


def seed_result(run: Run) -> dict[str, Any]:
    """One run: its final actor's episodes' max impacts (N), returns and successes, its r^sp per
    contact step at the end and its penalty weight's trajectory."""
    with open_checked(run.path / "final_eval_episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))

    def column(name: str) -> np.ndarray:
        return np.array([float(row.get(name) or "nan") for row in rows])

    weights = run.scalars.get("train/penalty_weight", (np.zeros(0), np.zeros(0)))
    return {
        "seed": int(run.config["seed"]),
        "impacts": column("max_impact") / float(run.setting("env", "force_scale", 1.0)),
        "returns": column("return"),
        "success": column("success"),
        "rsp_per_contact": _tail_mean(run, "train/penalty_surprise_per_contact_step"),
        "weights": weights,
    }


def method3_row(seeds: list[dict[str, Any]], hand: bool) -> dict[str, Any]:
    """One (task, variant) row: the score (success on the hand, return off it) as the mean over
    seeds of each run's mean and its std; the median and p90 max impact over every episode and
    the std of the per-run medians; r^sp per contact step (median over seeds)."""
    scores = [float(np.mean(s["success"] if hand else s["returns"])) for s in seeds]
    impacts = np.concatenate([s["impacts"] for s in seeds])
    medians = [float(np.median(s["impacts"])) for s in seeds]
    rsp = [s["rsp_per_contact"] for s in seeds if np.isfinite(s["rsp_per_contact"])]
    frames, weights = seeds[0]["weights"]
    return {
        "seeds": len(seeds),
        "first_seed": seeds[0]["seed"],
        "scores": scores,
        "score": statistics.mean(scores),
        "median_score": statistics.median(scores),
        "score_std": statistics.pstdev(scores),
        "median_impact": float(np.median(impacts)),
        "impact_std": statistics.pstdev(medians),
        "p90_impact": float(np.percentile(impacts, 90)),
        "rsp_per_contact": statistics.median(rsp) if rsp else float("nan"),
        "weights": [(int(f), float(w)) for f, w in zip(frames, weights, strict=True)],
    }


def load_method3(root: Path) -> dict[str, dict[str, dict[str, Any]]]:
    """task -> label -> its row (:func:`method3_row`), from the runs under ``root`` that have a
    ``final_eval_episodes.csv``."""
    grouped: dict[str, dict[str, list]] = {}
    for run in find_runs([root]):
        if not (run.path / "final_eval_episodes.csv").is_file():
            continue
        task = str(run.task).split(":", 1)[-1]
        grouped.setdefault(task, {}).setdefault(method3_label(run), []).append(seed_result(run))
    if not grouped:
        raise FileNotFoundError(f"no run with a final_eval_episodes.csv under {root}")
    return {
        task: {
            label: method3_row(sorted(seeds, key=lambda s: s["seed"]), task in ("touch", "fragile"))
            for label, seeds in labels.items()
        }
        for task, labels in sorted(grouped.items())
    }


def _trajectory(weights: list[tuple[int, float]], points: int = 6) -> str:
    """``w`` at ``points`` frames spread over the run, and its maximum."""
    picks = np.linspace(0, len(weights) - 1, min(points, len(weights))).round().astype(int)
    shown = ", ".join(f"{weights[i][1]:.2f} @ {weights[i][0] // 1000}k" for i in picks)
    return f"{shown} (max {max(w for _, w in weights):.2f})"


def method3_table(root: Path) -> str:
    """The markdown table, then each pre-registered test's verdict."""
    rows = load_method3(root)
    lines = [
        "| task | variant | success or return ± std (per seed) | median max impact ± std, p90 "
        "(N) | r^sp per contact step |",
        "| --- | --- | --- | --- | ---: |",
    ]
    for task, labels in rows.items():
        for label in (v for v in METHOD3_VARIANTS if v in labels):
            r = labels[label]
            per_seed = " / ".join(f"{x:.2f}" for x in r["scores"])
            lines.append(
                f"| {task} | `{label}` | {r['score']:.2f} ± {r['score_std']:.2f} ({per_seed}) | "
                f"{r['median_impact']:.2f} ± {r['impact_std']:.2f}, {r['p90_impact']:.2f} | "
                f"{r['rsp_per_contact']:.2f} |"
            )
    lines.append("")
    lines += [f"- **{name}**: {verdict}" for name, verdict in method3_verdicts(rows).items()]
    lines += [
        f"- penalty weight, {task} `{label}` seed {row['first_seed']}: {_trajectory(row['weights'])}"
        for task, labels in rows.items()
        for label, row in labels.items()
        if row["weights"]
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(method3_table, __doc__.splitlines()[0], "experiments/method3/table.py")
