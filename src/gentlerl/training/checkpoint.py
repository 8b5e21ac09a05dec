"""Atomic checkpoints: nothing half-written on disk, even when the process is killed mid-save."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import torch
from tensordict.nn import TensorDictModule
from torchrl.data import ReplayBuffer

from gentlerl.models import make_actor
from gentlerl.training.config import TrainConfig, make_config


def save_checkpoint(path: str | os.PathLike, state: dict[str, Any]) -> None:
    """``torch.save`` to a temporary file in the same directory, fsync, then ``os.replace``.

    ``os.replace`` is atomic on POSIX: a reader sees the old checkpoint or the new one, never a
    partial file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(state, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_checkpoint(path: str | os.PathLike) -> dict[str, Any]:
    """Load a checkpoint written by :func:`save_checkpoint` (it holds RNG states and counters)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}")
    return torch.load(path, map_location="cpu", weights_only=False)


def replay_buffer_state(rb: ReplayBuffer) -> dict[str, Any]:
    """``rb.state_dict()`` with only the filled part of a ``LazyTensorStorage``.

    TorchRL saves the whole pre-allocated storage (1M rows at paper scale); a half-empty buffer
    would write its empty rows too.
    """
    state = rb.state_dict()
    storage = rb.storage
    data = storage._storage[: len(storage)].clone() if storage.initialized else None
    state["_storage"] = {"data": data}
    return state


def load_replay_buffer_state(rb: ReplayBuffer, state: dict[str, Any]) -> None:
    """Inverse of :func:`replay_buffer_state` on a freshly built buffer of the same capacity."""
    data = state["_storage"]["data"]
    empty = {"_storage": {}, "initialized": False, "_len": 0}
    rb.load_state_dict({**state, "_storage": empty})
    if data is not None:
        rb.storage.set(torch.arange(len(data)), data)  # allocates the full capacity


def load_policy(path: str | os.PathLike) -> tuple[TrainConfig, TensorDictModule]:
    """The run's config and its deterministic actor (no exploration noise).

    ``path`` is a run's ``checkpoint.pt`` (the last actor) or ``best_policy.pt`` (the actor of its
    best evaluation).

    Rebuild the env with ``gentlerl.envs.make_env(cfg.task, seed=..., **cfg.env_kwargs)``.
    """
    state = load_checkpoint(path)
    cfg = make_config(**state["config"])
    actor = make_actor(state["obs_dim"], state["action_dim"], cfg.actor_hidden)
    actor.load_state_dict(state["actor"])
    return cfg, actor.eval()
