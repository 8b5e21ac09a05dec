"""Paper-style figures from run directories: ``gentlerl plot RUN_DIR... -o OUT``.

Draws what :mod:`gentlerl.plot` reads from run directories (or a sweep's runs). Figures (PNG):

- ``impact_histograms.png`` — maximum impact per training rollout (N) after the random warm-up
  (``init_random_frames``), rollouts with zero impact ignored, one panel per variant, lambda'_2
  values overlaid (paper Figs. 3 and 5);
- ``learning_curves.png`` — evaluation success rate (and return, where it differs) vs env frames:
  every evaluation a point, a line through the mean over seeds, a min-max band (paper Fig. 4);
- ``reward_components.png`` — mean of each reward component in the sampled batches vs frames,
  with a dashed line where the intrinsic rewards start (paper Fig. 6);
- ``summary.csv`` / ``summary.md`` — :func:`gentlerl.plot.summary_table`.
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from collections.abc import Iterable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gentlerl.plot import (  # noqa: E402
    EVAL_SUCCESS,
    Run,
    Series,
    find_runs,
    format_table,
    group_runs,
    max_impacts,
    seed_band,
    summary_table,
)


def plot_impact_histograms(runs: Sequence[Run], out: Path, bins: int = 30) -> Path:
    by_variant: dict[str, dict[str, list[Run]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        by_variant[f"{run.config.get('task')}: {run.config.get('variant')}"][run.label].append(run)
    fig, axes = plt.subplots(1, len(by_variant), figsize=(4 * len(by_variant), 3), squeeze=False)
    everything = max_impacts(runs)
    # A few very hard hits would squeeze the bulk into one bin: the last bin holds all >= p98.
    top = max(float(np.percentile(everything, 98)) if len(everything) else 1.0, 1e-3)
    edges = np.linspace(0, top, bins + 1)
    for ax, (title, labelled) in zip(axes[0], sorted(by_variant.items()), strict=True):
        for label, group in sorted(labelled.items()):
            ax.hist(np.minimum(max_impacts(group), top), bins=edges, alpha=0.6, label=label)
        xlabel = f"max impact per rollout (N), last bin >= {top:.1f}"
        ax.set(title=title, xlabel=xlabel, ylabel="rollouts")
        ax.legend(fontsize=7)
    return _save(fig, out / "impact_histograms.png")


def eval_points(series: Sequence[Series]) -> tuple[np.ndarray, ...]:
    """Every frame at which any seed evaluated, with the mean, min and max over those seeds.

    Evaluations are points, not a curve: nothing is interpolated, so a logged 1.0 at 15k frames
    and 0.0 at 20k frames stay 1.0 and 0.0 (the mean at a frame uses the seeds evaluated there).
    """
    by_frame: dict[float, list[float]] = defaultdict(list)
    for frames, values in series:
        for f, v in zip(frames.tolist(), values.tolist(), strict=True):
            by_frame[f].append(v)
    frames = sorted(by_frame)
    stats = np.array([(np.mean(v), np.min(v), np.max(v)) for v in map(by_frame.get, frames)])
    stats = stats.reshape(len(frames), 3)
    return np.array(frames, dtype=float), stats[:, 0], stats[:, 1], stats[:, 2]


def seeds_label(n: int) -> str:
    """``"1 seed"``, ``"3 seeds"``."""
    return f"{n} seed" if n == 1 else f"{n} seeds"


def distinct_metrics(runs: Sequence[Run], metrics: Sequence[tuple[str, str]]) -> list:
    """``metrics`` without those that repeat an earlier one's values in every run.

    On the touch task the evaluation return is the success rate (reward 1 on success, then the
    episode ends), so a second panel would repeat the first.
    """
    kept: list[tuple[str, str]] = []
    for name, label in metrics:
        logged = [r for r in runs if name in r.scalars]
        repeats = any(
            all(_same_series(r.scalars[name], r.scalars.get(other)) for r in logged)
            for other, _ in kept
        )
        if logged and not repeats:
            kept.append((name, label))
    return kept


def _same_series(a: Series, b: Series | None) -> bool:
    return (
        b is not None
        and a[0].shape == b[0].shape
        and bool(np.array_equal(a[0], b[0]) and np.allclose(a[1], b[1]))
    )


def learning_curves_figure(runs: Sequence[Run]) -> plt.Figure:
    """Evaluation metrics vs env frames: each seed's evaluations as small points, a line through
    the mean over seeds (with points) and a band from the min to the max over seeds."""
    metrics = distinct_metrics(runs, [(EVAL_SUCCESS, "success rate"), ("eval/return", "return")])
    metrics = metrics or [(EVAL_SUCCESS, "success rate")]
    fig, axes = plt.subplots(1, len(metrics), figsize=(5 * len(metrics), 3.5), squeeze=False)
    for ax, (name, ylabel) in zip(axes[0], metrics, strict=True):
        for (task, label), group in group_runs(runs).items():
            series = [r.scalars[name] for r in group if name in r.scalars]
            frames, mean, low, high = eval_points(series)
            if not len(frames):
                continue
            legend = f"{task}: {label} ({seeds_label(len(series))})"
            line = ax.plot(frames, mean, marker="o", markersize=4, label=legend)[0]
            colour = line.get_color()
            ax.fill_between(frames, low, high, color=colour, alpha=0.2, linewidth=0)
            for x, y in series:
                ax.plot(x, y, linestyle="none", marker="x", markersize=4, color=colour, alpha=0.7)
        ax.set(xlabel="env frames", ylabel=ylabel)
    axes[0, 0].legend(fontsize=7)
    return fig


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


def _first_on(series: Series | None) -> float | None:
    if series is None or not (series[1] > 0).any():
        return None
    return float(series[0][np.argmax(series[1] > 0)])


def _save(fig: plt.Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp")
    fig.savefig(tmp, dpi=90, format=path.suffix.lstrip("."))
    plt.close(fig)
    tmp.replace(path)
    return path


def build_parser(prog: str = "gentlerl plot") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument(
        "runs",
        nargs="+",
        help="run directories, folders of runs, or sweep files (recipes/sweeps/NAME.yaml: the "
        "runs of `gentlerl sweep` under SWEEPS_OUT/NAME)",
    )
    parser.add_argument("-o", "--out", default="figures", help="output folder for the PNGs")
    parser.add_argument(
        "--sweeps-out", default="runs/sweeps", help="where `gentlerl sweep --out` put its runs"
    )
    return parser


def resolve_run_paths(paths: Iterable[str], sweeps_out: str | Path) -> list[Path]:
    """Run folders as given, with each sweep file replaced by its runs' folder."""
    resolved = []
    for path in map(Path, paths):
        is_sweep = path.suffix in (".yaml", ".yml") and path.is_file()
        resolved.append(Path(sweeps_out) / path.stem if is_sweep else path)
    return resolved


def write_figures(runs: Sequence[Run], out: Path) -> list[Path]:
    """The paper-style figure set and the summary table (CSV and markdown) in ``out``."""
    paths = [
        plot_impact_histograms(runs, out),
        plot_learning_curves(runs, out),
        plot_reward_components(runs, out),
    ]
    rows = summary_table(runs)
    tmp = out / ".summary.csv.tmp"
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(out / "summary.csv")
    (out / ".summary.md.tmp").write_text(format_table(rows) + "\n")
    (out / ".summary.md.tmp").replace(out / "summary.md")
    return [*paths, out / "summary.csv", out / "summary.md"]


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl plot") -> None:
    """Write the figures and the summary table of the runs named on the command line."""
    args = build_parser(prog).parse_args(argv)
    runs = find_runs(resolve_run_paths(args.runs, args.sweeps_out))
    out = Path(args.out)
    for path in write_figures(runs, out):
        print(path)
    print(format_table(summary_table(runs)))


if __name__ == "__main__":
    main(prog="python -m gentlerl.figures")
