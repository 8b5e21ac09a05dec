"""Every file and folder of a run directory, named once.

The trainer writes through :class:`RunLayout`; the readers (``gentlerl plot``, sweeps, export,
claims, evaluate, calibration) read through it. A run directory holds::

    config.yaml               the run's full config (written at start)
    config_history.yaml       settings changed by each resume
    checkpoint.pt             everything needed to resume (last actor, critics, models, buffers)
    best_policy.pt            the actor of the best evaluation so far
    DONE                      written when the run has reached collector.total_frames
    .lock                     held while a trainer works in the directory
    logs/scalars/*.csv        one CSV per scalar (TorchRL CSVLogger, experiment "logs")
    eval_episodes.csv         one row per evaluation episode
    final_eval_episodes.csv   the final actor's episodes (``gentlerl evaluate --episodes-csv``)
    stdout.log                the trainer's output when a sweep runs it
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

CONFIG = "config.yaml"
CONFIG_HISTORY = "config_history.yaml"
CHECKPOINT = "checkpoint.pt"
BEST_POLICY = "best_policy.pt"
DONE = "DONE"
LOCK = ".lock"
#: TorchRL ``CSVLogger`` experiment name: scalars go to ``logs/scalars/<name>.csv``.
LOGS = "logs"
SCALARS = "scalars"
EVAL_EPISODES = "eval_episodes.csv"
FINAL_EVAL_EPISODES = "final_eval_episodes.csv"
STDOUT = "stdout.log"
#: The longest folder name and path (bytes) that Linux filesystems take.
NAME_MAX, PATH_MAX = 255, 4095


def run_dir_problem(run_dir: str) -> str | None:
    """Why ``run_dir`` cannot hold a run, in one line naming it (shortened when long), or
    ``None``: empty (the working folder), a folder name over :data:`NAME_MAX` bytes or a path
    over :data:`PATH_MAX`."""
    shown = repr(run_dir) if len(run_dir) <= 80 else f"{run_dir[:60]!r}... ({len(run_dir)} chars)"
    if not run_dir.strip():
        return f"run_dir={shown} must name a directory (empty: the working one)"
    name = next((n for n in Path(run_dir).parts if len(n.encode()) > NAME_MAX), None)
    if name is not None:
        return f"run_dir={shown}: a folder name is {len(name.encode())} bytes, over {NAME_MAX}"
    if len(os.fsencode(run_dir)) > PATH_MAX:
        return f"run_dir={shown} is longer than {PATH_MAX} bytes"
    return None


@dataclass(frozen=True)
class RunLayout:
    """The paths of one run directory ``root`` (nothing is created or checked)."""

    root: Path

    def __init__(self, root: str | os.PathLike) -> None:
        object.__setattr__(self, "root", Path(root))

    @property
    def config(self) -> Path:
        return self.root / CONFIG

    @property
    def config_history(self) -> Path:
        return self.root / CONFIG_HISTORY

    @property
    def checkpoint(self) -> Path:
        return self.root / CHECKPOINT

    @property
    def best_policy(self) -> Path:
        return self.root / BEST_POLICY

    @property
    def done(self) -> Path:
        return self.root / DONE

    @property
    def lock(self) -> Path:
        return self.root / LOCK

    @property
    def logs(self) -> Path:
        return self.root / LOGS

    @property
    def scalars(self) -> Path:
        return self.root / LOGS / SCALARS

    @property
    def eval_episodes(self) -> Path:
        return self.root / EVAL_EPISODES

    @property
    def final_eval_episodes(self) -> Path:
        return self.root / FINAL_EVAL_EPISODES

    @property
    def stdout(self) -> Path:
        return self.root / STDOUT

    def is_run(self) -> bool:
        """Whether ``root`` holds a run (its ``config.yaml``)."""
        return self.config.is_file()

    def has_started(self) -> bool:
        """Whether a trainer has written here (a checkpoint or logs)."""
        return self.checkpoint.exists() or self.logs.exists()
