"""Runs and their numbers: the run reader behind ``gentlerl plot`` and ``gentlerl claims``.

Reads the run directories the trainer writes (:class:`gentlerl.config.layout.RunLayout`: the
config, TorchRL ``CSVLogger`` scalars, the in-loop and final evaluation episodes); a ``RUN_DIR``
may also be a folder of runs (searched recursively). Runs that differ only by seed are grouped
(:func:`group_runs`). The paper's figure selections: :func:`after_intrinsic_start` (Fig. 3) and
:func:`successful_final_impacts` (Fig. 5). Imports nothing else of :mod:`gentlerl.analysis`.
"""

from __future__ import annotations

import functools
import os
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.lib import recfunctions

from gentlerl.config.layout import CONFIG, RunLayout
from gentlerl.files import load_yaml_file, open_checked, read_checked

Series = tuple[np.ndarray, np.ndarray]
EVAL_SUCCESS = "eval/success_rate"
#: The primary lambda'_2 per task: the claims' criteria judge ``r+rf+rsp`` at it.
PRIMARY_LAM2 = {"touch": 2.0, "fragile": 1.5, "explore": 2.0}


@dataclass
class Run:
    """One run directory's config and logged scalars (name -> (frames, values))."""

    path: Path
    config: dict
    scalars: dict[str, Series] = field(default_factory=dict)

    @property
    def layout(self) -> RunLayout:
        return RunLayout(self.path)

    def setting(self, group: str, name: str, default: Any = None) -> Any:
        """``config[group][name]``, or ``config[name]`` in a run of the earlier flat config."""
        return self.config.get(group, {}).get(name, self.config.get(name, default))

    @property
    def variant(self) -> str:
        return str(self.config.get("variant"))

    @property
    def lam2(self) -> float | None:
        """lambda'_2 of a penalty-surprise (``rsp``) variant; ``None`` for the others."""
        uses_lam = "rsp" in self.variant
        return float(self.setting("gentleness", "lam_prime", [None, None])[1]) if uses_lam else None

    @property
    def label(self) -> str:
        """The variant, its lambda'_2, and Method III's switches where on (``+ norm``, ``+ pid``,
        ``on the deployed policy``, ``w0=``): runs that differ in them are not pooled."""
        label = self.variant + (f" (λ'₂={self.lam2:g})" if self.lam2 is not None else "")
        if "rsp" in self.variant and self.setting("gentleness", "curiosity_norm", False):
            label += " + norm"
        if self.setting("gentleness", "multiplier", "none") != "none":
            label += f" + {self.setting('gentleness', 'multiplier')}"
            if self.setting("gentleness", "multiplier_episodes", 0):
                label += " on the deployed policy"
            if (base := float(self.setting("gentleness", "multiplier_base", 1.0))) != 1.0:
                label += f", w0={base:g}"
        return label

    @property
    def task(self) -> str | None:
        """The hand's task, or the external env a run trained on (``env.name``)."""
        return run_task(self.config)

    @property
    def group(self) -> tuple:
        return (self.task, self.label)


def run_task(config: Mapping[str, Any]) -> str | None:
    """The hand's task of a run's ``config``, or the external env it trained on (``env.name``)."""
    return (config.get("env") or {}).get("name") or config.get("task")


def _read_series(path: Path) -> Series:
    """``(frames, values)`` of a scalar CSV (``frame,value`` lines); a line that is not two
    numbers is an error naming the file and the line."""
    frames, values = [], []
    for number, line in enumerate(read_checked(path, errors="replace").splitlines(), 1):
        if line.strip():
            try:
                frame, value = map(float, line.split(","))
            except ValueError:
                raise ValueError(
                    f"{path}:{number}: expected 'frame,value', got {line[:60]!r}"
                ) from None
            frames.append(frame)
            values.append(value)
    return np.array(frames), np.array(values)


def load_run(path: str | Path) -> Run:
    """Load one run directory (it must hold its config)."""
    path = Path(path)
    layout = RunLayout(path)
    config_path = layout.config
    if not os.path.lexists(config_path):  # one that is not a file: refused by its reader
        raise FileNotFoundError(f"{path} is not a gentlerl run directory (no {CONFIG})")
    try:
        config = load_yaml_file(config_path, errors="replace")
    except yaml.YAMLError as err:
        raise ValueError(f"{config_path}: not valid YAML ({str(err).splitlines()[0]})") from None
    if not isinstance(config, dict) or not {"task", "variant", "seed"} <= set(config):
        raise ValueError(f"{config_path}: not a run's config (a mapping with task, variant, seed)")
    run = Run(path, config)
    scalars = layout.scalars
    for csv_path in sorted(scalars.rglob("*.csv")):
        run.scalars[str(csv_path.relative_to(scalars).with_suffix(""))] = _read_series(csv_path)
    return run


def find_runs(paths: Iterable[str | Path]) -> list[Run]:
    """Every run directory under ``paths`` (a path may itself be a run)."""
    runs = []
    for p in map(Path, paths):
        if not p.exists():
            raise FileNotFoundError(f"no such run directory: {p}")
        runs += [load_run(c.parent) for c in sorted(p.rglob(CONFIG))]
    if not runs:
        raise FileNotFoundError(f"no run directories (with {CONFIG}) under {list(paths)}")
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


def after_switch(run: Run, name: str) -> np.ndarray:
    """Values of the episode scalar ``name`` (``episode/max_impact``, ``episode/broken``...)
    logged after the run's :func:`intrinsic_start`."""
    frames, values = run.scalars.get(name, (np.zeros(0), np.zeros(0)))
    return values[frames > intrinsic_start(run)]


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
    parts = [after_switch(run, "episode/max_impact") for run in runs]
    values = np.concatenate(parts) if parts else np.zeros(0)
    return values if with_zeros else values[values > 0]


#: Outcome columns of an episodes CSV that an env without them (an external env) leaves out;
#: read back as NaN, so that every reader sees the same columns.
OUTCOME_COLUMNS = ("success", "broken")


def _episode_rows(path: Path) -> np.ndarray:
    """The rows of an episodes CSV (columns ``frames, episode, success, broken, max_impact,
    return``; :data:`OUTCOME_COLUMNS` NaN where the file has none) as a read-only structured
    array; empty if the file is missing or empty. A figure asks for the same files many times:
    each version of a file (path, mtime, size) is parsed once.
    """
    empty = np.zeros(0, dtype=[("frames", float), ("success", float), ("max_impact", float)])
    if not os.path.lexists(path):
        return empty
    with open_checked(path) as f:  # a link, a FIFO or a huge file: refused unread
        info = os.fstat(f.fileno())
    if info.st_size == 0:
        return empty
    return _parse_episodes(str(path), info.st_mtime_ns, info.st_size)


@functools.lru_cache(maxsize=512)
def _parse_episodes(path: str, mtime_ns: int, size: int) -> np.ndarray:
    """:func:`_episode_rows` of one version of a file (``mtime_ns`` and ``size`` key the cache)."""
    with open_checked(path, errors="replace") as f:
        rows = np.atleast_1d(np.genfromtxt(f, delimiter=",", names=True))
    missing = [c for c in OUTCOME_COLUMNS if c not in rows.dtype.names]
    if missing:
        nan = [np.full(len(rows), np.nan) for _ in missing]
        rows = recfunctions.append_fields(rows, missing, nan, usemask=False)
    rows.flags.writeable = False
    return rows


def in_loop_episodes(run: Run) -> np.ndarray:
    """The rows of every in-loop evaluation of the run (``eval_episodes.csv``; its ``frames``
    column says which evaluation); empty if none."""
    return _episode_rows(run.layout.eval_episodes)


def final_eval_episodes(run: Run) -> np.ndarray:
    """The rows of the run's last in-loop evaluation (``eval_episodes.csv``, the one at
    ``total_frames``: the final policy); empty if none."""
    rows = in_loop_episodes(run)
    return rows[rows["frames"] == rows["frames"].max()] if len(rows) else rows


def final_policy_episodes(run: Run) -> tuple[np.ndarray, str]:
    """Evaluation episodes of the run's final policy and where they come from.

    ``"evaluate"``: ``final_eval_episodes.csv``, written by ``gentlerl evaluate RUN/checkpoint.pt
    --episodes-csv RUN/final_eval_episodes.csv`` (the criteria's 20 episodes),
    when it evaluated an actor no older than the run's last in-loop evaluation; else
    ``"in-loop"``: the last in-loop evaluation (:func:`final_eval_episodes`); else ``"none"``.
    """
    rows = _episode_rows(run.layout.final_eval_episodes)
    in_loop = final_eval_episodes(run)
    if len(rows) and (not len(in_loop) or rows["frames"].min() >= in_loop["frames"].max()):
        return rows, "evaluate"
    return in_loop, "in-loop" if len(in_loop) else "none"


def successful_final_impacts(runs: Sequence[Run]) -> np.ndarray:
    """Paper Fig. 5's data: max impact (N) of the *successful* evaluation rollouts of each run's
    final policy (:func:`final_policy_episodes`, no exploration noise), over ``runs``."""
    parts = [
        rows["max_impact"][rows["success"] > 0] for rows, _ in map(final_policy_episodes, runs)
    ]
    return np.concatenate(parts) if parts else np.zeros(0)


def final_impacts(runs: Sequence[Run]) -> np.ndarray:
    """Max impact (N) of every evaluation rollout of each run's final policy, over ``runs``."""
    parts = [rows["max_impact"] for rows, _ in map(final_policy_episodes, runs)]
    return np.concatenate(parts) if parts else np.zeros(0)


def judged_by_success(runs: Sequence[Run]) -> bool:
    """Whether any final-policy episode of ``runs`` has a success outcome (an env without one,
    such as dm_control's finger, logs NaN and is judged by its return)."""
    return any(np.isfinite(rows["success"]).any() for rows, _ in map(final_policy_episodes, runs))


def final_sources(runs: Sequence[Run]) -> str:
    """Where the final-policy episodes of ``runs`` come from: one source, or ``"mixed"``."""
    sources = {final_policy_episodes(run)[1] for run in runs}
    return sources.pop() if len(sources) == 1 else "mixed"
