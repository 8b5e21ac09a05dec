"""Runs and their numbers: what ``gentlerl plot`` (:mod:`gentlerl.figures`) draws and tabulates.

Reads the layout written by :mod:`gentlerl.training` (``config.yaml``, TorchRL ``CSVLogger``
scalars under ``logs/scalars``, ``eval_episodes.csv``); a ``RUN_DIR`` may also be a folder of
runs (searched recursively). Runs that differ only by seed are grouped (:func:`group_runs`).
``python -m gentlerl.plot RUN_DIR... -o OUT`` is ``gentlerl plot``.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

Series = tuple[np.ndarray, np.ndarray]
EVAL_SUCCESS = "eval/success_rate"


@dataclass
class Run:
    """One run directory's config and logged scalars (name -> (frames, values))."""

    path: Path
    config: dict
    scalars: dict[str, Series] = field(default_factory=dict)

    def setting(self, group: str, name: str, default: Any = None) -> Any:
        """``config[group][name]``, or ``config[name]`` in a run of the earlier flat config."""
        return self.config.get(group, {}).get(name, self.config.get(name, default))

    @property
    def label(self) -> str:
        lam2 = self.setting("gentleness", "lam_prime", [None, None])[1]
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
    return values[frames > run.setting("collector", "init_random_frames", 0)]


def max_impacts(runs: Sequence[Run], *, with_zeros: bool = False) -> np.ndarray:
    """Max impact per training rollout after warm-up, over ``runs``; zero-impact ones removed
    unless ``with_zeros``."""
    values = [_after_warmup(run, "episode/max_impact") for run in runs]
    values = np.concatenate(values) if values else np.zeros(0)
    return values if with_zeros else values[values > 0]


def intrinsic_start(run: Run) -> float:
    """Env frame at which the run's intrinsic rewards switched on.

    The first frame where ``train/intrinsic_on`` reads 1; for a run without intrinsic rewards (or
    that never switched them on) the frame they would have started at, ``init_random_frames +
    reward_delay / utd_ratio`` (updates start after the warm-up, ``utd_ratio`` per frame), so
    that every variant of a grid is compared over the same part of training.
    """
    frames, on = run.scalars.get("train/intrinsic_on", (np.zeros(0), np.zeros(0)))
    if (on > 0).any():
        return float(frames[np.argmax(on > 0)])
    warmup = run.setting("collector", "init_random_frames", 0)
    delay = run.setting("gentleness", "reward_delay", 0)
    return float(warmup + delay / run.setting("learner", "utd_ratio", 1))


def after_intrinsic_start(runs: Sequence[Run], *, with_zeros: bool = False) -> np.ndarray:
    """Paper Fig. 3's data: max impact (N) of the training rollouts logged after each run's
    :func:`intrinsic_start`, over ``runs``; zero-impact rollouts removed unless ``with_zeros``."""
    parts = []
    for run in runs:
        frames, values = run.scalars.get("episode/max_impact", (np.zeros(0), np.zeros(0)))
        parts.append(values[frames > intrinsic_start(run)])
    values = np.concatenate(parts) if parts else np.zeros(0)
    return values if with_zeros else values[values > 0]


def final_eval_episodes(run: Run) -> np.ndarray:
    """The rows of the run's last evaluation in ``eval_episodes.csv`` (structured array with the
    columns ``frames, episode, success, broken, max_impact, return``); empty if none."""
    path = run.path / "eval_episodes.csv"
    if not path.is_file() or path.stat().st_size == 0:
        return np.zeros(0, dtype=[("frames", float), ("success", float), ("max_impact", float)])
    rows = np.atleast_1d(np.genfromtxt(path, delimiter=",", names=True))
    return rows[rows["frames"] == rows["frames"].max()] if len(rows) else rows


def successful_final_impacts(runs: Sequence[Run]) -> np.ndarray:
    """Paper Fig. 5's data: max impact (N) of the *successful* evaluation rollouts of each run's
    final policy (its last evaluation, no exploration noise), over ``runs``."""
    parts = [rows["max_impact"][rows["success"] > 0] for rows in map(final_eval_episodes, runs)]
    return np.concatenate(parts) if parts else np.zeros(0)


def _first_success(run: Run, threshold: float = 0.8) -> float:
    frames, success = run.scalars.get(EVAL_SUCCESS, (np.zeros(0), np.zeros(0)))
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
        evals = [r.scalars[EVAL_SUCCESS][1] for r in group if EVAL_SUCCESS in r.scalars]
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


if __name__ == "__main__":
    from gentlerl.figures import main

    main(prog="python -m gentlerl.plot")
