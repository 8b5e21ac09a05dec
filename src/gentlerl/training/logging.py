"""Run logging: TorchRL loggers (CSV always, wandb or tensorboard on request) and episode statistics.

Layout of a run directory (read by :mod:`gentlerl.analysis.runs`): ``config.yaml``; one CSV per
scalar under ``logs/scalars/<name>.csv`` (rows ``step,value``; step = env frames collected);
``eval_episodes.csv`` (one row per evaluation episode); ``checkpoint.pt``; ``DONE``.
"""

from __future__ import annotations

import csv
import math
import time
from collections import deque
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.envs.transforms import RewardSum, StepCounter, Transform
from torchrl.record.loggers import Logger, get_logger
from tqdm.auto import tqdm

from gentlerl import keys
from gentlerl.config.layout import LOGS, RunLayout
from gentlerl.files import open_append, read_checked, write_atomic
from gentlerl.functional import excess_cost
from gentlerl.training.evaluation import OUTCOMES

#: The columns of an episodes CSV; ``success`` and ``broken`` only where the env defines them.
EVAL_COLUMNS = ("frames", "episode", "success", "broken", "max_impact", "return", "cost")


class RunLogger:
    """Scalars to TorchRL's CSV logger and, with ``logger="wandb"`` / ``"tensorboard"``, to that
    logger too (all through ``torchrl.record.loggers.get_logger``).

    wandb writes under ``run_dir/wandb`` and stays silent unless ``wandb_mode="online"`` (which
    prints the run's link); tensorboard event files go to ``run_dir/tensorboard``.
    """

    def __init__(
        self,
        run_dir: str | Path,
        config: dict[str, Any],
        wandb_mode: str = "offline",
        project: str = "gentlerl",
        logger: str = "csv",
    ) -> None:
        self.run_dir = Path(run_dir)
        self.layout = RunLayout(run_dir)
        self.loggers: list[Logger] = [get_logger("csv", str(self.run_dir), LOGS)]
        if logger == "wandb" and wandb_mode != "disabled":
            import wandb

            quiet = wandb_mode == "offline"
            wandb_kwargs = dict(
                offline=quiet, project=project, config=config, settings=wandb.Settings(silent=quiet)
            )
            self.loggers.append(
                get_logger("wandb", str(self.run_dir), self.run_dir.name, wandb_kwargs=wandb_kwargs)
            )
        elif logger == "tensorboard":
            try:
                import tensorboard  # noqa: F401  (torch's SummaryWriter needs it)
            except ImportError as err:
                raise ImportError(
                    "logger=tensorboard needs the tensorboard package: pip install "
                    "'gentlerl[tensorboard]'"
                ) from err
            self.loggers.append(get_logger("tensorboard", str(self.run_dir), "tensorboard"))
        elif logger not in ("csv", "wandb"):
            raise ValueError(f"logger must be one of csv, wandb, tensorboard; got {logger!r}")

    def log(self, scalars: dict[str, float], step: int) -> None:
        for logger in self.loggers:
            for name, value in scalars.items():
                logger.log_scalar(name, float(value), step=step)

    def close(self) -> None:
        """Finish the wandb run / flush the tensorboard writer (their files are complete after)."""
        for logger in self.loggers[1:]:
            experiment = logger.experiment
            (getattr(experiment, "finish", None) or experiment.close)()

    def truncate_after(self, frames: int) -> None:
        """Drop rows logged after ``frames`` (a resumed run re-collects them; no duplicated steps)."""
        episodes = self.layout.eval_episodes
        for path in [*self.layout.scalars.glob("**/*.csv"), episodes]:
            if not path.is_file():
                continue
            lines = read_checked(path).splitlines(keepends=True)
            header = lines[:1] if path == episodes else []
            kept = [row for row in lines[len(header) :] if int(row.split(",", 1)[0]) <= frames]
            write_atomic(path, "".join(header + kept))

    def log_eval_episodes(self, frames: int, episodes: list[dict[str, float]]) -> None:
        path = self.layout.eval_episodes
        header, rows = episode_table(frames, episodes)
        new = not path.exists()
        with open_append(path, newline="") as f:
            writer = csv.writer(f)
            if new:
                writer.writerow(header)
            writer.writerows(rows)


def episode_table(frames: int, episodes: Sequence[Mapping[str, float]]) -> tuple[list, list]:
    """The header and rows of an episodes CSV (:data:`EVAL_COLUMNS` less the outcomes the
    episodes do not have: an external env without ``success`` / ``broken``), outcomes as 0/1."""
    columns = [c for c in EVAL_COLUMNS[2:] if episodes and c in episodes[0]]
    rows = [
        [frames, i, *(int(ep[c]) if c in OUTCOMES else ep[c] for c in columns)]
        for i, ep in enumerate(episodes)
    ]
    return ["frames", "episode", *columns], rows


#: What :func:`episode_transforms` write (at the root and under ``"next"``); read, then dropped.
EPISODE_KEYS = ("step_count", f"episode_{keys.REWARD}")


def episode_transforms() -> list[Transform]:
    """TorchRL's ``StepCounter`` and ``RewardSum`` (of the env's ``reward``) for the collection env.

    They write ``("next", "step_count")`` and ``("next", "episode_reward")``, which
    :class:`EpisodeStats` reads at the end of each episode as its length and task return.
    A list, to append one by one: TorchRL cannot find the parent env of a ``Compose`` nested first
    in another.
    """
    return [StepCounter(), RewardSum(in_keys=[keys.REWARD])]


class EpisodeStats:
    """Per-episode statistics of collected batches (episodes span batches).

    Length and task return come from the collection env's :func:`episode_transforms`, read at the
    step whose ``("next", "done")`` is set. What those transforms cannot give is accumulated here,
    per trajectory (the collector's trajectory ids, and the batch row, one per worker, for
    ``[workers, T]`` batches):

    - the returns of the other reward components (``penalty``, the surprises): they are written
      by the reward transforms on collected batches, with the learner's current models, not by
      the env, so an env-side ``RewardSum`` never sees them;
    - maxima over the episode (success, broken, the impact over steps and sites in N, and with a
      force watchdog, ``DriverHandEnv``, whether it ended the episode): ``RewardSum`` only sums
      reward entries.
    """

    def __init__(self, reward_keys: list[str], tolerance: float | None = None) -> None:
        self.summed = [k for k in dict.fromkeys(reward_keys) if k != keys.REWARD]
        #: With a tolerance, each episode's ``cost``: the sum of :func:`excess_cost`.
        self.tolerance = tolerance
        self._open: dict[int, dict[str, float]] = {}

    def update(self, batch: TensorDictBase) -> list[dict[str, float]]:
        """Accumulate a batch; returns the statistics of the episodes it ends, in trajectory order."""
        traj = batch.get(("collector", "traj_ids"))
        if batch.ndim == 2:  # [workers, T]: Ray workers number their trajectories independently
            traj = traj + (torch.arange(batch.shape[0]) << 40).unsqueeze(-1)
        nxt, traj = batch.get("next").reshape(-1), traj.reshape(-1)
        done = nxt.get(keys.DONE).reshape(-1)
        sums = {f"return_{k}": nxt.get(k).reshape(-1) for k in self.summed}
        if self.tolerance is not None:
            sums["cost"] = excess_cost(nxt.get(keys.IMPACT).reshape(len(nxt), -1), self.tolerance)
        # success / broken only where the env has them (an external env may not)
        maxima = {
            key: nxt.get(key).reshape(-1).float()
            for key in (keys.SUCCESS, keys.BROKEN)
            if key in nxt.keys()
        }
        maxima["max_impact"] = nxt.get(keys.IMPACT).reshape(len(nxt), -1).amax(-1)
        if keys.WATCHDOG in nxt.keys():
            maxima["watchdog"] = nxt.get(keys.WATCHDOG).reshape(-1).float()
        finished = []
        for tid in torch.unique(traj).tolist():
            mask = traj == tid
            stats = self._open.setdefault(tid, dict.fromkeys([*sums, *maxima], 0.0))
            for name, column in sums.items():
                stats[name] += column[mask].sum().item()
            for name, column in maxima.items():
                stats[name] = _peak(stats[name], column[mask].max().item())
            if done[mask].any():
                last = nxt[(mask & done).nonzero()[0, 0]]
                stats["return_reward"] = last.get(f"episode_{keys.REWARD}").item()
                stats["length"] = float(last.get("step_count").item())
                finished.append(self._open.pop(tid))
        return finished


def _peak(so_far: float, new: float) -> float:
    """The larger of two maxima, NaN when either is: python's ``max(0.0, nan)`` is 0.0, which
    would log an episode with one NaN step at its other steps' max (or 0 N)."""
    return math.nan if math.isnan(new) else max(so_far, new)


def force_unit(force_scale: float = 1.0) -> str:
    """The unit of reported forces and impacts: N, or with an external env's ``env.force_scale``
    the scaled unit (0.01: ``100 N``)."""
    return "N" if force_scale == 1.0 else f"{1.0 / force_scale:g} N"


def progress_postfix(
    recent: Sequence[Mapping[str, float]],
    eval_history: Sequence[Mapping[str, float]],
    unit: str = "N",
) -> dict[str, str]:
    """The progress bar's fields: the mean success (or return) and max impact (in ``unit``) of
    the ``recent`` training episodes, and the last evaluation's success rate (or return)."""

    def mean(name: str) -> float:
        return float(np.mean([e[name] for e in recent])) if recent else 0.0

    # Without success in the env (an external env), the bar shows the returns instead.
    judged = "success" if not recent or "success" in recent[-1] else "return_reward"
    last = dict(eval_history[-1]) if eval_history else {}
    shown = last.get("success_rate", last.get("return"))
    return {  # the speed is tqdm's own frame/s: one speed on the bar
        judged.removeprefix("return_"): f"{mean(judged):.2f}",
        "max_impact": f"{mean('max_impact'):.2f} {unit}",
        "eval": "-" if shown is None else f"{shown:.2f}",
    }


class Progress:
    """The loop's progress: the statistics of the episodes it collects (the last 20 kept for the
    bar), its env steps per second, and its tqdm bar (shown with ``enabled``; ``bar``: its line
    and label where several bars show at once)."""

    def __init__(
        self,
        reward_keys: list[str],
        total: int,
        frames: int,
        enabled: bool,
        unit: str = "N",
        bar: tuple[int, str] | None = None,
        tolerance: float | None = None,
    ) -> None:
        self.episodes = EpisodeStats(reward_keys, tolerance)
        self.unit = unit
        self.recent: deque[dict[str, float]] = deque(maxlen=20)
        position, desc = bar if bar is not None else (None, None)
        self.bar = tqdm(
            total=total, initial=frames, disable=not enabled, unit="frame",
            position=position, desc=desc,
        )  # fmt: skip
        self._start, self._start_frames = time.perf_counter(), frames

    def finished_episodes(self, batch: TensorDictBase) -> list[dict[str, float]]:
        """:meth:`EpisodeStats.update`, the episodes also kept for the bar."""
        finished = self.episodes.update(batch)
        self.recent.extend(finished)
        return finished

    def env_steps_per_s(self, frames: int) -> float:
        """Frames collected per second since the loop started, ``frames`` collected in all."""
        return (frames - self._start_frames) / max(time.perf_counter() - self._start, 1e-9)

    def advance(self, batch_frames: int, eval_history: Sequence[Mapping[str, float]]) -> None:
        self.bar.update(batch_frames)
        self.bar.set_postfix(progress_postfix(self.recent, eval_history, self.unit))

    def close(self) -> None:
        self.bar.close()
