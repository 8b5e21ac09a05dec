"""Paper-style figures from run directories: ``python -m gentlerl.plot RUN_DIR... -o OUT``.

Reads the layout written by :mod:`gentlerl.training` (``config.yaml``, TorchRL ``CSVLogger``
scalars under ``logs/scalars``, ``eval_episodes.csv``); a ``RUN_DIR`` may also be a folder of
runs (searched recursively). Runs that differ only by seed are grouped: curves show the mean and
the min-max spread over seeds. Figures (PNG):

- ``impact_histograms.png`` — maximum impact per training rollout (N) after the random warm-up
  (``init_random_frames``), rollouts with zero impact ignored, one panel per variant, lambda'_2
  values overlaid (paper Figs. 3 and 5);
- ``learning_curves.png`` — evaluation success rate and return vs env frames (paper Fig. 4);
- ``reward_components.png`` — mean of each reward component in the sampled batches vs frames,
  with a dashed line where the intrinsic rewards start (paper Fig. 6).
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

Series = tuple[np.ndarray, np.ndarray]


@dataclass
class Run:
    """One run directory's config and logged scalars (name -> (frames, values))."""

    path: Path
    config: dict
    scalars: dict[str, Series] = field(default_factory=dict)

    @property
    def label(self) -> str:
        lam2 = self.config.get("lam_prime", [None, None])[1]
        uses_lam = "rsp" in self.config.get("variant", "")
        return f"{self.config.get('variant')}" + (f" (λ'₂={lam2:g})" if uses_lam else "")

    @property
    def group(self) -> tuple:
        return (self.config.get("task"), self.label)


def _read_series(path: Path) -> Series:
    rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
    if not rows:
        return np.zeros(0), np.zeros(0)
    data = np.array(rows, dtype=float)
    return data[:, 0], data[:, 1]


def load_run(path: str | Path) -> Run:
    """Load one run directory (it must hold ``config.yaml``)."""
    path = Path(path)
    config_path = path / "config.yaml"
    if not config_path.is_file():
        raise FileNotFoundError(f"{path} is not a gentlerl run directory (no config.yaml)")
    run = Run(path, yaml.safe_load(config_path.read_text()))
    scalars = path / "logs" / "scalars"
    for csv_path in sorted(scalars.rglob("*.csv")):
        run.scalars[str(csv_path.relative_to(scalars).with_suffix(""))] = _read_series(csv_path)
    return run


def find_runs(paths: Iterable[str | Path]) -> list[Run]:
    """Every run directory under ``paths`` (a path may itself be a run)."""
    runs = []
    for p in map(Path, paths):
        if not p.exists():
            raise FileNotFoundError(f"no such run directory: {p}")
        runs += [load_run(c.parent) for c in sorted(p.rglob("config.yaml"))]
    if not runs:
        raise FileNotFoundError(f"no run directories (with config.yaml) under {list(paths)}")
    return runs


def group_runs(runs: Sequence[Run]) -> dict[tuple, list[Run]]:
    groups: dict[tuple, list[Run]] = defaultdict(list)
    for run in runs:
        groups[run.group].append(run)
    return dict(sorted(groups.items(), key=lambda kv: tuple(map(str, kv[0]))))


def seed_band(series: Sequence[Series], points: int = 50) -> tuple[np.ndarray, ...]:
    """Mean, min and max over seeds on a common frame grid (linear interpolation)."""
    series = [s for s in series if len(s[0])]
    if not series:
        return (np.zeros(0),) * 4
    end = min(s[0][-1] for s in series)
    start = max(s[0][0] for s in series)
    grid = np.linspace(start, end, points) if end > start else np.array([end])
    values = np.stack([np.interp(grid, x, y) for x, y in series])
    return grid, values.mean(0), values.min(0), values.max(0)


def _after_warmup(run: Run, name: str) -> np.ndarray:
    """Values of episode scalar ``name`` logged after the run's random warm-up frames.

    Rollouts of the first ``init_random_frames`` come from a uniformly random policy, not from the
    variant; at CPU scale they are a large share of a short run, so statistics leave them out.
    """
    frames, values = run.scalars.get(name, (np.zeros(0), np.zeros(0)))
    return values[frames > run.config.get("init_random_frames", 0)]


def max_impacts(runs: Sequence[Run], *, with_zeros: bool = False) -> np.ndarray:
    """Max impact per training rollout after warm-up, over ``runs``; zero-impact ones removed
    unless ``with_zeros``."""
    values = [_after_warmup(run, "episode/max_impact") for run in runs]
    values = np.concatenate(values) if values else np.zeros(0)
    return values if with_zeros else values[values > 0]


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


def plot_learning_curves(runs: Sequence[Run], out: Path) -> Path:
    metrics = [("eval/success_rate", "success rate"), ("eval/return", "return")]
    fig, axes = plt.subplots(1, len(metrics), figsize=(10, 3.5))
    for ax, (name, ylabel) in zip(axes, metrics, strict=True):
        for (task, label), group in group_runs(runs).items():
            grid, mean, low, high = seed_band([r.scalars[name] for r in group if name in r.scalars])
            if len(grid):
                line = ax.plot(grid, mean, label=f"{task}: {label} ({len(group)} seeds)")[0]
                ax.fill_between(grid, low, high, color=line.get_color(), alpha=0.2)
        ax.set(xlabel="env frames", ylabel=ylabel)
    axes[0].legend(fontsize=7)
    return _save(fig, out / "learning_curves.png")


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
        ax.set(title=f"{task}: {label}", xlabel="env frames", ylabel="mean reward in batch")
        ax.legend(fontsize=7)
    return _save(fig, out / "reward_components.png")


def _first_on(series: Series | None) -> float | None:
    if series is None or not (series[1] > 0).any():
        return None
    return float(series[0][np.argmax(series[1] > 0)])


def _save(fig: plt.Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


_EVAL = "eval/success_rate"


def _first_success(run: Run, threshold: float = 0.8) -> float:
    frames, success = run.scalars.get(_EVAL, (np.zeros(0), np.zeros(0)))
    hits = frames[success >= threshold]
    return float(hits[0]) if len(hits) else float("nan")


def summary_table(runs: Sequence[Run]) -> list[dict[str, object]]:
    """Per group (runs that differ only by seed), the numbers the paper's claims are about.

    Training rollouts after the random warm-up: ``contact_share`` (share with any impact),
    ``mean/median/p90_max_impact`` and ``share_over_5N`` (of the rollouts with impact, N),
    ``broken_share``. Evaluation: ``final_success`` and ``mean_eval_success`` (mean over seeds of
    the last / of all evaluations), ``seeds_reaching_0.8`` and ``first_0.8_frames`` (mean over the
    seeds that reached an evaluation success rate >= 0.8).
    """
    rows, nan = [], float("nan")
    for (task, label), group in group_runs(runs).items():
        evals = [r.scalars[_EVAL][1] for r in group if _EVAL in r.scalars]
        all_impacts = max_impacts(group, with_zeros=True)
        impacts = all_impacts[all_impacts > 0]
        broken = np.concatenate([_after_warmup(r, "episode/broken") for r in group])
        first = np.array([_first_success(r) for r in group])
        reached = first[~np.isnan(first)]
        rows.append(
            {
                "task": task,
                "variant": label,
                "seeds": len(group),
                "final_success": float(np.mean([e[-1] for e in evals])) if evals else nan,
                "mean_eval_success": float(np.mean([e.mean() for e in evals])) if evals else nan,
                "seeds_reaching_0.8": len(reached),
                "first_0.8_frames": float(reached.mean()) if len(reached) else nan,
                "rollouts": len(all_impacts),
                "contact_share": _share(len(impacts), len(all_impacts)),
                "mean_max_impact": float(impacts.mean()) if len(impacts) else 0.0,
                "median_max_impact": float(np.median(impacts)) if len(impacts) else 0.0,
                "p90_max_impact": float(np.percentile(impacts, 90)) if len(impacts) else 0.0,
                "share_over_5N": _share(int((impacts > 5).sum()), len(impacts)),
                "broken_share": _share(int(broken.sum()), len(broken)),
            }
        )
    return rows


def _share(part: int, whole: int) -> float:
    return part / whole if whole else float("nan")  # no rollouts: undefined, not 0


def _cell(value: object) -> str:
    return f"{value:.2f}" if isinstance(value, float) else str(value)


def format_table(rows: Sequence[dict[str, object]]) -> str:
    """``rows`` of :func:`summary_table` as a markdown table (floats to 2 decimals)."""
    names = list(rows[0])
    lines = ["| " + " | ".join(names) + " |", "|" + " --- |" * len(names)]
    lines += ["| " + " | ".join(_cell(row[n]) for n in names) + " |" for row in rows]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m gentlerl.plot", description=__doc__.splitlines()[0]
    )
    parser.add_argument("runs", nargs="+", help="run directories or folders of runs")
    parser.add_argument("-o", "--out", default="figures", help="output folder for the PNGs")
    args = parser.parse_args(argv)
    runs = find_runs(args.runs)
    out = Path(args.out)
    for path in (
        plot_impact_histograms(runs, out),
        plot_learning_curves(runs, out),
        plot_reward_components(runs, out),
    ):
        print(path)
    with (out / "summary.csv").open("w", newline="") as f:
        rows = summary_table(runs)
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out / "summary.md").write_text(format_table(rows) + "\n")
    print(out / "summary.csv")
    print(format_table(rows))


if __name__ == "__main__":
    main()
