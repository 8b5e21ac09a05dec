"""The rules of resuming a run: the checkpoint it continues, the settings that changed since,
and whether it is done.

Resuming (``resume``): ``false`` refuses a run directory that already holds a run, ``true`` needs
its checkpoint, ``"auto"`` continues it when there is one and starts otherwise. *Structural*
fields (those not declared ``resumable``: task, variant, seed, network sizes, supports, reward
parameters, buffer layout, env) must equal the checkpoint's; the :data:`SAFE_TO_CHANGE` ones may
change and each change is appended to ``config_history.yaml`` in the run directory.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from gentlerl.config.fields import resumable
from gentlerl.config.layout import RunLayout
from gentlerl.files import dump_yaml, load_yaml_file, write_atomic
from gentlerl.training.checkpoint import load_checkpoint
from gentlerl.training.config import TrainConfig
from gentlerl.training.migration import group_flat_config

#: Fields a resumed run may change (declared ``resumable``): how long and how fast it goes on, and
#: what it logs. The rest shape the saved networks and buffers or the rewards already stored in them.
SAFE_TO_CHANGE = resumable(TrainConfig)
#: Not settings of the run: never recorded as changes.
_LOCATION = frozenset({"run_dir", "resume"})


def flatten(config: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"group.field": value}`` of a nested config dict, tuples as lists (as YAML keeps them)."""
    flat: dict[str, Any] = {}
    for name, value in config.items():
        if isinstance(value, Mapping) and name != "kwargs":
            flat.update(flatten(value, f"{prefix}{name}."))
        else:
            flat[f"{prefix}{name}"] = plain(value)
    return flat


def plain(value: Any) -> Any:
    """Tuples to lists, recursively, so a config dumps (and compares) as plain YAML."""
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


def config_changes(saved: Mapping[str, Any], now: Mapping[str, Any]) -> dict[str, tuple]:
    """``{field: (saved value, current value)}`` for every field that differs."""
    old, new = flatten(saved), flatten(now)
    names = sorted(set(old) | set(new))
    return {n: (old.get(n), new.get(n)) for n in names if old.get(n) != new.get(n)}


def load_resume_state(cfg: TrainConfig, checkpoint: Path) -> dict[str, Any] | None:
    """The checkpoint to continue the run ``cfg`` from, or ``None`` to start;
    raises before anything is written.

    Raises:
        ValueError: a run exists and ``resume=false``; ``resume=true`` without a checkpoint;
            structural fields differ from the checkpoint's (one line listing them).
    """
    run_dir, resume = checkpoint.parent, cfg.resume
    if resume is False:
        if RunLayout(run_dir).has_started():  # its checkpoint, or logs of a run that began
            raise ValueError(
                f"run_dir={str(run_dir)!r} already holds a run; pass resume=true to continue it "
                "(resume=auto: continue it or start), or choose another run_dir"
            )
        return None
    if not checkpoint.exists():
        if resume is True:
            raise ValueError(
                f"resume=true but there is no checkpoint to resume at {checkpoint}; check "
                "run_dir, or pass resume=auto to start the run when it has none"
            )
        return None
    state = load_checkpoint(checkpoint)
    if not isinstance(state.get("config"), dict):
        raise ValueError(f"{checkpoint}: it lacks its config (a mapping); it cannot be resumed")
    changes = config_changes(group_flat_config(state["config"]), cfg.to_dict())
    structural = [n for n in changes if n not in SAFE_TO_CHANGE]
    if structural:
        listed = ", ".join(f"{n} ({changes[n][0]!r} -> {changes[n][1]!r})" for n in structural)
        raise ValueError(
            f"cannot resume {checkpoint}: structural settings differ from the checkpoint's: "
            f"{listed}; resume with the checkpoint's values or start a new run_dir"
        )
    return state


def finished_summary(state: Mapping[str, Any], done_marker: Path, cfg: TrainConfig) -> dict | None:
    """The final evaluation of a run that is done (not to be run again); else ``None``, and a run
    given a longer ``total_frames`` loses its ``done_marker`` until it is done again."""
    if state["counters"]["frames"] < cfg.collector.total_frames:
        done_marker.unlink(missing_ok=True)
        return None
    if not done_marker.exists() or not state["eval_history"]:
        return None
    last = state["eval_history"][-1]
    print(
        f"{done_marker.parent} finished at {last['frames']} frames: not run again", file=sys.stderr
    )
    return {k: v for k, v in last.items() if k != "frames"}


def record_config_changes(run_dir: Path, state: Mapping, now: Mapping) -> list[str]:
    """Append the safe changes since the checkpoint ``state`` to ``config_history.yaml``; their
    names."""
    frames = state["counters"]["frames"]
    saved = group_flat_config(state["config"])
    changes = {n: v for n, v in config_changes(saved, now).items() if n not in _LOCATION}
    if not changes:
        return []
    path = RunLayout(run_dir).config_history
    history = _history(path)
    entry = {n: {"was": old, "now": new} for n, (old, new) in changes.items()}
    history.append({"resumed_at_frame": int(frames), "changed": entry})
    write_atomic(path, dump_yaml(history, sort_keys=False))
    return sorted(changes)


def _history(path: Path) -> list:
    """The entries of ``config_history.yaml`` (none if it is missing or empty); a file that is
    not a YAML list is an error naming it."""
    if not path.exists():
        return []
    try:
        history = load_yaml_file(path, errors="replace")
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    if history is None:
        return []
    if not isinstance(history, list):
        raise ValueError(f"{path} must be a YAML list of changes, got a {type(history).__name__}")
    return history


def checked_counters(counters: Mapping[str, Any], checkpoint: Path) -> dict[str, Any]:
    """A checkpoint's ``frames`` / ``updates`` / ``update_credit``: finite and >= 0, else a
    one-line ``ValueError`` naming the file."""
    bad = {
        k: v
        for k, v in counters.items()
        if not isinstance(v, int | float) or not math.isfinite(v) or v < 0
    }
    if bad:
        raise ValueError(f"{checkpoint}: counters {bad} must be finite and >= 0; it cannot resume")
    return dict(counters)
