"""Paper-style figures from run directories (the ``gentlerl plot`` command is
:mod:`gentlerl.apps.plot`).

Draws what :mod:`gentlerl.analysis.runs` reads from run directories (or a sweep's runs). Figures
(PNG):

- ``impact_histograms.png`` (paper Fig. 3) — max impact per training rollout (N) after the intrinsic
  rewards switch on (:func:`gentlerl.analysis.runs.after_intrinsic_start`), touching rollouts only,
  one panel per variant, lambda'_2 values overlaid;
- ``final_impacts.png`` (paper Fig. 5) — max impact of the successful evaluation rollouts of each
  run's final policy (:func:`gentlerl.analysis.runs.successful_final_impacts`; the legend names the
  episodes' source and says when a variant has none);
- ``learning_curves.png`` (paper Fig. 4) — evaluation success rate (and return, where it differs) vs
  env frames, one panel per claim, points with min-max bars (:mod:`gentlerl.analysis.curves`);
- ``reward_components.png`` (paper Fig. 6) — mean of each reward component in the sampled
  batches vs frames, with a dashed line where the intrinsic rewards start;
- ``return_vs_impact.png`` — one point per run: its final policy's success rate (return where the
  env has no success outcome) against the median of its per-episode max impact in N (an external
  env's ``env.force_scale`` undone), one panel per task, one colour per variant;
- ``summary.csv`` / ``summary.md`` — :func:`gentlerl.analysis.summary.summary_table`, the same
  selections.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gentlerl.analysis.curves import learning_curves_figure, seeds_label  # noqa: E402
from gentlerl.analysis.runs import (  # noqa: E402
    Run,
    Series,
    after_intrinsic_start,
    final_impacts,
    final_policy_episodes,
    final_sources,
    group_runs,
    judged_by_success,
    seed_band,
    successful_final_impacts,
)
from gentlerl.analysis.summary import summary_markdown, summary_table  # noqa: E402
from gentlerl.config.layout import FINAL_EVAL_EPISODES  # noqa: E402
from gentlerl.files import spreadsheet_safe, write_atomic  # noqa: E402


def _impact_panels(runs: Sequence[Run]) -> dict[str, dict[str, list[Run]]]:
    """Panel title (task and variant) -> label (lambda'_2 for rsp variants) -> runs."""
    panels: dict[str, dict[str, list[Run]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        panels[f"{run.task}: {run.variant}"][run.label].append(run)
    return dict(sorted(panels.items()))


def _histograms(runs: Sequence[Run], select: Callable, note: Callable, title: str) -> plt.Figure:
    """One panel per variant (4 to a row), lambda'_2 values overlaid; ``select(runs)`` gives the
    impacts and ``note(runs, values)`` each legend entry's text. A panel without data says so."""
    panels = _impact_panels(runs)
    cols = min(len(panels), 4)
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows + 0.6), squeeze=False)
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    everything = select(list(runs))
    # A few very hard hits would squeeze the bulk into one bin: the last bin holds all >= p98.
    top = max(float(np.percentile(everything, 98)) if len(everything) else 1.0, 1e-3)
    edges = np.linspace(0, top, 31)
    for ax, (panel, labelled) in zip(axes.flat, panels.items(), strict=False):
        drawn = 0
        for label, group in sorted(labelled.items()):
            values = select(group)
            drawn += len(values)
            text = f"{label}: {note(group, values)}"
            ax.hist(np.minimum(values, top), bins=edges, alpha=0.6, label=text)
        if not drawn:
            ax.text(0.5, 0.5, "no rollouts in this selection", ha="center", transform=ax.transAxes)
        ax.set(title=panel, xlabel=f"max impact (N), last bin >= {top:.1f}", ylabel="rollouts")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), fontsize=7, frameon=False)
    fig.suptitle(title, fontsize=10)
    return fig


def plot_impact_histograms(runs: Sequence[Run], out: Path) -> Path:
    """Paper Fig. 3: max impact of the touching training rollouts after the intrinsic rewards
    switch on (:func:`gentlerl.analysis.runs.after_intrinsic_start`)."""

    def note(group: list[Run], values: np.ndarray) -> str:
        every = after_intrinsic_start(group, with_zeros=True)
        return f"{len(values)} touching of {len(every)} ({seeds_label(len(group))})"

    title = "Max impact per touching training rollout after the intrinsic rewards switch on"
    fig = _histograms(runs, after_intrinsic_start, note, title)
    return _save(fig, out / "impact_histograms.png")


def plot_final_impacts(runs: Sequence[Run], out: Path) -> Path:
    """Paper Fig. 5: max impact of the successful rollouts of each run's final policy
    (:func:`gentlerl.analysis.runs.successful_final_impacts`), or of all its rollouts for an env
    without a success outcome (decided per panel); the legend names the episodes' source."""

    def select(group: Sequence[Run]) -> np.ndarray:
        by_success = judged_by_success(group)
        return successful_final_impacts(group) if by_success else final_impacts(group)

    def note(group: list[Run], values: np.ndarray) -> str:
        episodes = sum(len(final_policy_episodes(r)[0]) for r in group)
        if not episodes:
            return "no final-policy episodes"
        which = "successful " if judged_by_success(group) else ""
        return f"{len(values)} {which}of {episodes} ({final_sources(group)})"

    every = (
        ""
        if all(map(judged_by_success, group_runs(runs).values()))
        else " (every one where the env has no success outcome)"
    )
    title = (
        f"Max impact per successful rollout of the final policy{every} (episodes: evaluate = "
        f"{FINAL_EVAL_EPISODES}, in-loop = the run's last evaluation)"
    )
    fig = _histograms(runs, select, note, title)
    return _save(fig, out / "final_impacts.png")


def plot_learning_curves(runs: Sequence[Run], out: Path) -> Path:
    return _save(learning_curves_figure(runs), out / "learning_curves.png")


def plot_reward_components(runs: Sequence[Run], out: Path) -> Path:
    groups = group_runs(runs)
    cols = min(len(groups), 4)
    rows = -(-len(groups) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.5 * cols, 3.2 * rows), squeeze=False)
    for ax in axes.flat[len(groups) :]:
        ax.set_visible(False)
    for ax, ((task, label), group) in zip(axes.flat, groups.items(), strict=False):
        ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(4))
        names = sorted({n for r in group for n in r.scalars if n.startswith("train/batch_")})
        for name in names:
            grid, mean, low, high = seed_band([r.scalars[name] for r in group if name in r.scalars])
            ax.plot(grid, mean, label=name.removeprefix("train/batch_"))
        starts = [_first_on(r.scalars.get("train/intrinsic_on")) for r in group]
        starts = [s for s in starts if s is not None]
        if starts:
            ax.axvline(min(starts), color="k", linestyle="--", linewidth=1)
        title = f"{task}: {label} ({seeds_label(len(group))})"
        ax.set(title=title, xlabel="env frames", ylabel="mean reward in batch")
        ax.legend(fontsize=7)
    return _save(fig, out / "reward_components.png")


def plot_return_vs_impact(runs: Sequence[Run], out: Path) -> Path:
    """One point per run: final-policy success (or mean return) vs median max impact (N)."""
    tasks = sorted({str(r.task) for r in runs})
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.5 * len(tasks), 3.4), squeeze=False)
    colours = {}
    for ax, task in zip(axes.flat, tasks, strict=True):
        group = [r for r in runs if str(r.task) == task]
        by_success = judged_by_success(group)
        for run in group:
            rows, _ = final_policy_episodes(run)
            if not len(rows):
                continue
            newtons = rows["max_impact"] / float(run.setting("env", "force_scale", 1.0) or 1.0)
            # numpy.genfromtxt renames the column "return", a python keyword, to "return_".
            y = np.nanmean(rows["success"] if by_success else rows["return_"])
            colour = colours.setdefault(run.label, f"C{len(colours)}")
            ax.scatter(np.median(newtons), y, color=colour, label=run.label, s=25)
        handles, labels = ax.get_legend_handles_labels()
        unique = dict(zip(labels, handles, strict=True))
        ax.legend(unique.values(), unique.keys(), fontsize=7)
        ylabel = "final success rate" if by_success else "final mean return"
        ax.set(title=task, xlabel="median max impact per episode (N)", ylabel=ylabel)
    return _save(fig, out / "return_vs_impact.png")


def _first_on(series: Series | None) -> float | None:
    if series is None or not (series[1] > 0).any():
        return None
    return float(series[0][np.argmax(series[1] > 0)])


def _save(fig: plt.Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp")
    # "tight" keeps the legends drawn outside the axes inside the image.
    fig.savefig(tmp, dpi=90, format=path.suffix.lstrip("."), bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


def write_figures(runs: Sequence[Run], out: Path) -> list[Path]:
    """The paper-style figure set and the summary table (CSV and markdown) in ``out``."""
    paths = [
        plot_impact_histograms(runs, out),
        plot_final_impacts(runs, out),
        plot_learning_curves(runs, out),
        plot_reward_components(runs, out),
        plot_return_vs_impact(runs, out),
    ]
    rows = summary_table(runs)

    def write_csv(f: IO) -> None:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows({k: spreadsheet_safe(v) for k, v in row.items()} for row in rows)

    write_atomic(out / "summary.csv", write_csv, newline="")
    write_atomic(out / "summary.md", summary_markdown(rows))
    return [*paths, out / "summary.csv", out / "summary.md"]
