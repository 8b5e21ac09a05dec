"""Checkpoints: atomic (nothing half-written on disk, even when the process is killed mid-save)
and loaded without running code from the file.

Files hold only tensors and plain Python containers, so :func:`load_checkpoint` reads them with
``torch.load(weights_only=True)``: a shared ``best_policy.pt`` cannot execute anything. The few
objects a run's state holds besides those (tensordicts, the prioritised sampler's trees, numpy's
RNG state) are written as tagged plain dicts and rebuilt on load.
"""

from __future__ import annotations

import errno
import math
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.data import ReplayBuffer

from gentlerl.data.prioritized import FlatPriorityTree
from gentlerl.files import FileRefusedError, open_checked, write_atomic
from gentlerl.models import make_actor
from gentlerl.training.config import TrainConfig, make_config
from gentlerl.training.migration import group_flat_config
from gentlerl.training.policy_weights import actor_weights_problem
from gentlerl.training.state_checks import replay_state_problem


class CheckpointError(ValueError):
    """A checkpoint or policy file that cannot be read; the message names the file."""


_TD, _TREE, _ARRAY = "__tensordict__", "__priority_tree__", "__ndarray__"


def _to_plain(obj: Any) -> Any:
    """``obj`` with tensordicts, priority trees and numpy arrays as tagged plain dicts (numpy
    scalars as Python numbers)."""
    if isinstance(obj, TensorDictBase):
        # Entry by entry, not ``to_dict()``: a nested tensordict keeps its own batch size (an
        # n-step transition's ``[n]`` window of steps).
        entries = {k: _to_plain(v) for k, v in obj.items()}
        return {_TD: entries, "batch_size": list(obj.batch_size)}
    if isinstance(obj, FlatPriorityTree):
        return {_TREE: obj.reduce, "values": obj.values}
    if isinstance(obj, np.ndarray):
        return {_ARRAY: torch.from_numpy(obj.copy())}
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, torch.Tensor) and _is_view_of_more(obj):
        # ``torch.save`` writes a view's whole storage: a seed's row of a seed group's stacked
        # parameters would carry every seed's values
        return obj.detach().clone()
    if isinstance(obj, dict):
        return {k: _to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_to_plain(v) for v in obj)
    return obj


def _is_view_of_more(tensor: torch.Tensor) -> bool:
    """Whether ``tensor`` (dense) sees only part of its storage."""
    if tensor.layout != torch.strided:
        return False
    return tensor.untyped_storage().nbytes() > tensor.numel() * tensor.element_size()


def _from_plain(obj: Any) -> Any:
    """Inverse of :func:`_to_plain`."""
    if isinstance(obj, dict):
        if _TD in obj:
            return TensorDict(_from_plain(obj[_TD]), batch_size=obj["batch_size"])
        if _TREE in obj:
            tree = FlatPriorityTree(len(obj["values"]), obj[_TREE], obj["values"].dtype)
            tree.values = obj["values"]
            return tree
        if _ARRAY in obj:
            return obj[_ARRAY].numpy()
        return {k: _from_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_from_plain(v) for v in obj)
    return obj


def remove_stale_temp_files(run_dir: str | os.PathLike) -> list[Path]:
    """Delete the ``.<name>.*.tmp`` files a process killed inside :func:`save_checkpoint` left."""
    stale = sorted(Path(run_dir).glob(".*.pt.*.tmp"))
    for tmp in stale:
        tmp.unlink(missing_ok=True)
    return stale


def save_checkpoint(path: str | os.PathLike, state: dict[str, Any]) -> None:
    """``torch.save`` to a temporary file in the same directory, fsync, then ``os.replace``.

    ``os.replace`` is atomic on POSIX: a reader sees the old checkpoint or the new one, never a
    partial file. ``state`` may hold tensors, plain containers, tensordicts, numpy arrays and
    :class:`~gentlerl.data.prioritized.FlatPriorityTree` (see the module docstring).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        write_atomic(path, lambda f: torch.save(_to_plain(state), f), binary=True)
    except BaseException as err:
        if isinstance(err.__context__, KeyboardInterrupt) and not isinstance(
            err, KeyboardInterrupt
        ):
            # Ctrl-C or SIGTERM inside torch.save: its zip writer's exit then fails with a
            # RuntimeError ("unexpected pos"); the interrupt is what happened (the old file and
            # no partial one are left, as write_atomic promises)
            raise err.__context__ from None
        if isinstance(err, RuntimeError | OSError) and _out_of_space(err, path.parent):
            kept = f"{path} is intact" if path.exists() else f"no {path.name} was written"
            raise OSError(
                errno.ENOSPC, f"no space left on device writing {path} ({kept}); free some space"
            ) from None
        raise


def _out_of_space(err: BaseException, folder: Path) -> bool:
    """Whether a failed save ran out of disk: ``ENOSPC``, or torch's zip writer failing
    (``[enforce fail at inline_container.cc]``, "file write failed") with under 64 MiB free."""
    if isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT):
        return True
    message = str(err)
    if "inline_container" not in message and "write failed" not in message:
        return False
    return shutil.disk_usage(folder).free < 64 * 2**20


def load_checkpoint(path: str | os.PathLike) -> dict[str, Any]:
    """Load a file written by :func:`save_checkpoint`, executing no code from it.

    Raises:
        FileNotFoundError: no file at ``path``.
        CheckpointError: a truncated, corrupt or foreign file (one line naming it).
    """
    path = Path(path)
    try:
        f = open_checked(path, cap=None, binary=True)  # a link, a FIFO, /dev/zero: refused unread
    except FileNotFoundError:
        raise FileNotFoundError(f"no checkpoint at {path}") from None
    except FileRefusedError as err:
        raise CheckpointError(str(err)) from None
    try:
        with f:
            state = torch.load(f, map_location="cpu", weights_only=True)
    except Exception as err:  # damaged bytes fail anywhere in the unpickler (KeyError, EOFError...)
        lines = str(err).strip().splitlines() or [type(err).__name__]
        # torch's weights-only refusal explains itself on the "Unsupported global" line.
        reason = next((line for line in lines if "Unsupported global" in line), lines[0])
        reason = reason.strip().split(" was not an allowed global")[0].split(". ")[0]
        raise CheckpointError(
            f"cannot read checkpoint {path} ({reason[:120]}): it is truncated, corrupt, or not "
            "written by this gentlerl; restore a good copy, or delete it to start the run afresh"
        ) from None
    if not isinstance(state, dict):
        raise CheckpointError(f"{path} holds a {type(state).__name__}, not a gentlerl checkpoint")
    return _from_plain(state)


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


def load_replay_buffer_state(
    rb: ReplayBuffer, state: dict[str, Any], path: str | os.PathLike | None = None
) -> None:
    """Inverse of :func:`replay_buffer_state` on a freshly built buffer of the same capacity;
    a replay that :func:`replay_state_problem` refuses is a :class:`CheckpointError` naming
    ``path``, raised before the buffer is touched."""
    problem = replay_state_problem(state, rb.storage.max_size)
    if problem is not None:
        raise CheckpointError(f"{path or 'the checkpoint'}: {problem}; it cannot be resumed")
    data = state["_storage"]["data"]
    empty = {"_storage": {}, "initialized": False, "_len": 0}
    rb.load_state_dict({**state, "_storage": empty})
    if data is not None:
        rb.storage.set(torch.arange(len(data)), data)  # allocates the full capacity


def critic_supports(critic: torch.nn.Module) -> dict[str, list[float]]:
    """Each head's ``v_min`` / ``v_max`` of a :class:`~gentlerl.models.FusedCritic` (or of the
    ``TensorDictModule`` around it): the atoms its logits are read on, saved beside its weights."""
    module = getattr(critic, "module", critic)
    return {"v_min": [float(v) for v in module.v_min], "v_max": [float(v) for v in module.v_max]}


def check_critic_supports(
    state: dict[str, Any], critic: torch.nn.Module, path: str | os.PathLike
) -> None:
    """Refuse (``ValueError``, one line) critic weights that trained on other supports than the
    ``critic`` built from the config: their logits would be read on the wrong atoms.

    A checkpoint saved before supports were saved has no ``"supports"``; its config is read with
    the behaviour of its time (:func:`~gentlerl.training.migration.group_flat_config`).
    """
    saved = state.get("supports")
    if saved is None:
        return
    now = critic_supports(critic)
    same = all(
        len(saved[k]) == len(now[k])
        and all(
            abs(a - b) <= 1e-6 * max(1.0, abs(a)) for a, b in zip(saved[k], now[k], strict=False)
        )
        for k in ("v_min", "v_max")
    )
    if not same:
        raise ValueError(
            f"{path}: its critics trained on supports v_min={saved['v_min']}, "
            f"v_max={saved['v_max']}, but this config builds v_min={now['v_min']}, "
            f"v_max={now['v_max']} (check network.v_min / v_max / dense_reward_bound and the "
            "env's time_limit)"
        )


#: What :func:`load_policy` needs from a file: the run's config, the actor's sizes and weights.
POLICY_KEYS = ("config", "obs_dim", "action_dim", "actor")


def policy_from_state(
    state: dict[str, Any], path: str | os.PathLike
) -> tuple[TrainConfig, TensorDictModule]:
    """The config and deterministic actor held by a loaded checkpoint or policy ``state``
    (``path`` names the file in errors)."""
    missing = [k for k in POLICY_KEYS if k not in state]
    if missing:
        raise CheckpointError(f"{path} is not a gentlerl policy file: it lacks {missing}")
    if not isinstance(state["config"], dict):
        raise CheckpointError(f"{path}: its config is a {type(state['config']).__name__}")
    try:
        cfg = make_config(**group_flat_config(state["config"]))
    except (ValueError, TypeError) as err:
        reason = "; ".join(line.strip(" -") for line in str(err).splitlines()[1:]) or str(err)
        raise CheckpointError(f"{path}: its config is invalid: {reason}") from None
    sizes = (state["obs_dim"], state["action_dim"], cfg.network.actor_hidden)
    problem = actor_weights_problem(state["actor"], sizes)
    if problem is not None:
        raise CheckpointError(f"{path}: {problem}")
    actor = make_actor(*sizes)
    actor.load_state_dict(state["actor"])
    return cfg, actor.eval()


def load_policy(path: str | os.PathLike) -> tuple[TrainConfig, TensorDictModule]:
    """The run's config and its deterministic actor (no exploration noise).

    ``path`` is a run's ``checkpoint.pt`` (the last actor), ``best_policy.pt`` (the actor of its
    best evaluation) or a file of :func:`export_policy`, also one saved with the flat config of
    older versions (:func:`~gentlerl.training.migration.group_flat_config`).

    Rebuild the env with ``gentlerl.envs.make_env(cfg.task, seed=..., **cfg.env.kwargs)``.
    """
    return policy_from_state(load_checkpoint(path), path)


def policy_frames(state: dict[str, Any]) -> int | None:
    """Env frames the actor in ``state`` trained for: a checkpoint's ``counters``, a
    ``best_policy.pt``'s evaluation, an exported policy's ``frames``; ``None`` if unknown.

    Raises:
        CheckpointError: the count is there but not a whole number >= 0 (a NaN).
    """
    if isinstance(state.get("counters"), dict) and "frames" in state["counters"]:
        return _frames(state["counters"]["frames"])
    if isinstance(state.get("eval"), dict) and "frames" in state["eval"]:
        return _frames(state["eval"]["frames"])
    return None if state.get("frames") is None else _frames(state["frames"])


def checked_policy_frames(state: dict[str, Any], path: str | os.PathLike) -> int | None:
    """:func:`policy_frames`, its refusal naming the file ``path``."""
    try:
        return policy_frames(state)
    except CheckpointError as err:
        raise CheckpointError(f"{path}: {err}") from None


def _frames(value: Any) -> int:
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if not number or not math.isfinite(value) or value < 0 or value != int(value):
        raise CheckpointError(f"its frame count {value!r} is not a whole number >= 0")
    return int(value)


def policy_file_state(state: dict[str, Any], path: str | os.PathLike) -> dict[str, Any]:
    """The part of a loaded checkpoint ``state`` that :func:`load_policy` needs (config, actor
    sizes and weights; the config in the current grouped layout) and the frames it trained for;
    ``path`` names the file in errors."""
    cfg, _ = policy_from_state(state, path)  # refuses a file load_policy could not read
    policy = {k: state[k] for k in POLICY_KEYS}
    return {**policy, "config": cfg.to_dict(), "frames": checked_policy_frames(state, path)}


def export_policy(source: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Write the policy of ``source`` (a run's ``checkpoint.pt`` or ``best_policy.pt``) to
    ``out``, atomically (:func:`save_checkpoint`): :func:`policy_file_state`, without the replay
    buffers, critics, surprise models and optimiser state of a checkpoint.

    :func:`load_policy` and ``gentlerl evaluate`` read the file. Returns ``out``.
    """
    save_checkpoint(out, policy_file_state(load_checkpoint(source), source))
    return Path(out)
