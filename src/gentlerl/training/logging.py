"""Run logging: TorchRL loggers (CSV always, wandb optionally) and per-episode statistics.

Layout of a run directory (read by :mod:`gentlerl.plot`): ``config.yaml``; one CSV per scalar
under ``logs/scalars/<name>.csv`` (rows ``step,value``; step = env frames collected);
``eval_episodes.csv`` (one row per evaluation episode); ``checkpoint.pt``; ``DONE``.
"""

from __future__ import annotations

import csv
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDictBase
from torchrl.record.loggers import CSVLogger, Logger

from gentlerl import keys

EVAL_COLUMNS = ("frames", "episode", "success", "broken", "max_impact", "return")


class RunLogger:
    """Writes scalars to TorchRL's ``CSVLogger`` and, unless disabled, a ``WandbLogger``."""

    def __init__(
        self, run_dir: str | Path, config: dict[str, Any], wandb_mode: str, project: str
    ) -> None:
        self.run_dir = Path(run_dir)
        self.loggers: list[Logger] = [CSVLogger(exp_name="logs", log_dir=str(self.run_dir))]
        if wandb_mode != "disabled":
            from torchrl.record.loggers import WandbLogger

            self.loggers.append(
                WandbLogger(
                    exp_name=self.run_dir.name,
                    offline=wandb_mode == "offline",
                    save_dir=str(self.run_dir),
                    project=project,
                    config=config,
                )
            )

    def log(self, scalars: dict[str, float], step: int) -> None:
        for logger in self.loggers:
            for name, value in scalars.items():
                logger.log_scalar(name, float(value), step=step)

    def close(self) -> None:
        """Finish the wandb run (its offline files are complete afterwards)."""
        for logger in self.loggers[1:]:
            logger.experiment.finish()

    def truncate_after(self, frames: int) -> None:
        """Drop rows logged after ``frames`` (a resumed run re-collects them; no duplicated steps)."""
        for path in [
            *self.run_dir.glob("logs/scalars/**/*.csv"),
            self.run_dir / "eval_episodes.csv",
        ]:
            if not path.is_file():
                continue
            lines = path.read_text().splitlines(keepends=True)
            header = lines[:1] if path.name == "eval_episodes.csv" else []
            kept = [row for row in lines[len(header) :] if int(row.split(",", 1)[0]) <= frames]
            tmp = path.with_suffix(".csv.tmp")
            tmp.write_text("".join(header + kept))
            os.replace(tmp, path)

    def log_eval_episodes(self, frames: int, episodes: list[dict[str, float]]) -> None:
        path = self.run_dir / "eval_episodes.csv"
        new = not path.exists()
        with path.open("a", newline="") as f:
            writer = csv.writer(f)
            if new:
                writer.writerow(EVAL_COLUMNS)
            for i, ep in enumerate(episodes):
                writer.writerow(
                    [
                        frames,
                        i,
                        int(ep["success"]),
                        int(ep["broken"]),
                        ep["max_impact"],
                        ep["return"],
                    ]
                )


class EpisodeTracker:
    """Accumulates per-episode statistics over collector batches (episodes span batches).

    Episodes are told apart by the collector's trajectory ids (and the batch row, one per
    worker, for ``[workers, T]`` batches); an episode is reported once its
    ``("next", "done")`` flag is seen. Per episode: the return of each reward component, success,
    broken, the maximum impact over steps and sites (N), and the length; with a force watchdog
    (``DriverHandEnv``), ``watchdog``: whether it ended the episode.
    """

    def __init__(self, reward_keys: list[str]) -> None:
        self.reward_keys = list(dict.fromkeys([keys.REWARD, *reward_keys]))
        self._open: dict[int, dict[str, float]] = defaultdict(self._empty)

    def _empty(self) -> dict[str, float]:
        stats = {f"return_{k}": 0.0 for k in self.reward_keys}
        stats.update(success=0.0, broken=0.0, max_impact=0.0, length=0.0)
        return stats

    def update(self, batch: TensorDictBase) -> list[dict[str, float]]:
        traj = batch.get(("collector", "traj_ids"))
        if batch.ndim == 2:  # [workers, T]: Ray workers number their trajectories independently
            traj = traj + (torch.arange(batch.shape[0]) << 40).unsqueeze(-1)
        batch, traj = batch.reshape(-1), traj.reshape(-1)
        nxt = batch.get("next")
        done = nxt.get(keys.DONE).reshape(-1)
        columns = {f"return_{k}": nxt.get(k).reshape(-1) for k in self.reward_keys}
        impact = nxt.get(keys.IMPACT).reshape(len(batch), -1).amax(-1)
        success = nxt.get(keys.SUCCESS).reshape(-1).float()
        broken = nxt.get(keys.BROKEN).reshape(-1).float()
        watchdog = nxt.get(keys.WATCHDOG, None)
        if watchdog is not None:
            watchdog = watchdog.reshape(-1).float()
        finished = []
        for tid in torch.unique(traj).tolist():
            mask = traj == tid
            stats = self._open[tid]
            for name, column in columns.items():
                stats[name] += column[mask].sum().item()
            stats["max_impact"] = max(stats["max_impact"], impact[mask].max().item())
            stats["success"] = max(stats["success"], success[mask].max().item())
            stats["broken"] = max(stats["broken"], broken[mask].max().item())
            stats["length"] += mask.sum().item()
            if watchdog is not None:
                stats["watchdog"] = max(stats.get("watchdog", 0.0), watchdog[mask].max().item())
            if done[mask].any():
                finished.append(self._open.pop(tid))
        return finished
