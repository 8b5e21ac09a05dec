"""What a checkpoint must hold before a run resumes from it: every entry checked against the
trainer built from the config, before anything is restored.

A crafted or damaged ``checkpoint.pt`` is refused in one line naming the file and each field
that is wrong: a field missing, networks whose names, shapes or dtypes are not the model's, a
NaN where the model holds finite values, Adam moments that are not their parameters'
(:func:`~gentlerl.models.stacking.optimizer_row_problem`; the fused kernel would write past its
buffers), counters that are not finite counts (``frames=NaN`` read as a finished run), a
non-finite clock or evaluation, random-generator states that do not load. The replays are
checked where they are loaded (:func:`~gentlerl.training.state_checks.replay_state_problem`).
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from gentlerl.models.stacking import optimizer_row_problem

if TYPE_CHECKING:
    import os

    from gentlerl.training.seed_run import SeedRun

#: The entries every checkpoint of a run holds (older ones lack ``wall_s`` and ``supports``).
REQUIRED = (
    "config", "learner", "intrinsic", "rb", "nstep", "model_rb", "counters", "eval_history",
    "best_eval", "rng",
)  # fmt: skip
#: The learner's entries (:class:`~gentlerl.agent.learner.TrainingState`).
LEARNER = ("networks", "optimizer", "target_counter")
#: The counters a run keeps: whole counts, and the fractional update credit.
COUNTS, CREDIT = ("frames", "updates"), "update_credit"
#: The largest count a checkpoint may hold (frames and updates of any real run are far below).
MAX_COUNT = 2**53


class CheckpointSchemaError(ValueError):
    """A checkpoint that does not fit the run resuming it; the message names the file and the
    fields, on one line."""


def check_trainer_state(trainer: SeedRun, state: Any, path: str | os.PathLike) -> None:
    """Raise :class:`CheckpointSchemaError` when ``state`` (a loaded checkpoint) cannot be
    restored into ``trainer``, listing every
    problem; ``path`` names the file."""
    problems = trainer_state_problems(trainer, state)
    if problems:
        shown = "; ".join(problems[:5]) + (
            f"; and {len(problems) - 5} more" if len(problems) > 5 else ""
        )
        raise CheckpointSchemaError(f"{path}: {shown}; it cannot be resumed")


def trainer_state_problems(trainer: SeedRun, state: Any) -> list[str]:
    """Why ``state`` cannot be restored into ``trainer``, one line per field (none: it can)."""
    if not isinstance(state, Mapping):
        return [f"it holds a {type(state).__name__}, not a run's state"]
    missing = [k for k in REQUIRED if k not in state]
    if missing:
        return [f"it lacks the field(s) {missing}"]
    problems = [*_learner_problems(trainer, state["learner"])]
    problems += _intrinsic_problems(trainer, state["intrinsic"])
    problems += _counter_problems(state["counters"])
    wall = state.get("wall_s", 0.0)
    if not _number(wall) or not 0 <= wall < math.inf:
        problems.append(f"wall_s={wall!r} is not a finite number of seconds >= 0")
    problems += _eval_problems(state["eval_history"], state["best_eval"])
    if trainer.beta_schedule is not None:
        problems += _finite_like(
            "beta_schedule", state.get("beta_schedule"), trainer.beta_schedule.state_dict()
        )
    if problem := _rng_problem(state["rng"]):
        problems.append(f"rng: {problem}")
    return problems


def _learner_problems(trainer: SeedRun, learner: Any) -> list[str]:
    if not isinstance(learner, Mapping):
        return [f"learner is a {type(learner).__name__}, not a mapping"]
    missing = [f"learner.{k}" for k in LEARNER if k not in learner]
    if missing:
        return [f"it lacks the field(s) {missing}"]
    problems = tensors_problems("learner.networks", learner["networks"], trainer.loss.state_dict())
    if problem := optimizer_row_problem(trainer.learner.optimizer, learner["optimizer"]):
        problems.append(f"learner.optimizer {problem}")
    if not _count(learner["target_counter"]):
        problems.append(f"learner.target_counter={learner['target_counter']!r} is not a count >= 0")
    return problems


def _intrinsic_problems(trainer: SeedRun, intrinsic: Any) -> list[str]:
    rewards = trainer.rewards
    if not isinstance(intrinsic, Mapping):
        return [f"intrinsic is a {type(intrinsic).__name__}, not a mapping"]
    missing = [f"intrinsic.{k}" for k in ("losses", "optimizers", "target_counters", "active")]
    missing = [k for k in missing if k.split(".")[1] not in intrinsic]
    if missing:
        return [f"it lacks the field(s) {missing}"]
    problems = []
    for name, loss in rewards.losses.items():
        for field, saved in (
            ("losses", intrinsic["losses"]),
            ("optimizers", intrinsic["optimizers"]),
        ):
            if not isinstance(saved, Mapping) or name not in saved:
                problems.append(f"it lacks intrinsic.{field}.{name}")
        if problems:
            continue
        where = f"intrinsic.losses.{name}"
        problems += tensors_problems(where, intrinsic["losses"][name], loss.state_dict())
        optimizer = rewards.steps[name].optimizer
        if problem := optimizer_row_problem(optimizer, intrinsic["optimizers"][name]):
            problems.append(f"intrinsic.optimizers.{name} {problem}")
    counters = intrinsic["target_counters"]
    if not isinstance(counters, Mapping) or not set(counters) <= set(rewards.losses):
        problems.append(f"intrinsic.target_counters {counters!r} are not the models' counters")
    else:
        problems += [
            f"intrinsic.target_counters.{k}={v!r} is not a count >= 0"
            for k, v in counters.items()
            if not _count(v)
        ]
    if not _count(intrinsic.get("num_updates", 0)):
        problems.append(f"intrinsic.num_updates={intrinsic['num_updates']!r} is not a count >= 0")
    return problems


def _counter_problems(counters: Any) -> list[str]:
    if not isinstance(counters, Mapping):
        return [f"counters is a {type(counters).__name__}, not a mapping"]
    missing = [f"counters.{k}" for k in (*COUNTS, CREDIT) if k not in counters]
    if missing:
        return [f"it lacks the field(s) {missing}"]
    problems = [
        f"counters.{k}={counters[k]!r} is not a count >= 0"
        for k in COUNTS
        if not _count(counters[k])
    ]
    credit = counters[CREDIT]
    if not _number(credit) or not 0 <= credit < MAX_COUNT:
        problems.append(f"counters.{CREDIT}={credit!r} is not a finite number >= 0")
    return problems


def _eval_problems(history: Any, best: Any) -> list[str]:
    if not isinstance(history, list):
        return [f"eval_history is a {type(history).__name__}, not a list"]
    problems = []
    for i, entry in enumerate(history):
        if problem := _eval_problem(entry):
            problems.append(f"eval_history[{i}] {problem}")
            break
    if best is not None and (problem := _eval_problem(best)):
        problems.append(f"best_eval {problem}")
    return problems


def _eval_problem(entry: Any) -> str | None:
    """An evaluation: its ``frames`` a count, each value a number (NaN where it was not
    measured: an env without ``success``), never infinite."""
    if not isinstance(entry, Mapping) or not _count(entry.get("frames")):
        return "is not an evaluation (a mapping with its frames)"
    bad = {k: v for k, v in entry.items() if not _number(v) or math.isinf(v)}
    return f"holds {bad}, not finite numbers" if bad else None


def tensors_problems(field: str, saved: Any, live: Mapping[str, Any]) -> list[str]:
    """Why the tensors ``saved`` (a state dict) cannot load into a module whose state dict is
    ``live``: names, shapes and dtypes must be the same, and a value NaN or infinite only where
    the module's own is."""
    if not isinstance(saved, Mapping):
        return [f"{field} is a {type(saved).__name__}, not a state dict"]
    missing, extra = sorted(set(live) - set(saved)), sorted(set(saved) - set(live), key=str)
    if missing or extra:
        return [f"{field} lacks {missing[:3]} and holds unknown {extra[:3]}"]
    for key, own in live.items():
        value = saved[key]
        if not isinstance(own, torch.Tensor):
            continue
        if not isinstance(value, torch.Tensor):
            return [f"{field}.{key} is a {type(value).__name__}, not a tensor"]
        if value.shape != own.shape or value.dtype != own.dtype:
            return [
                f"{field}.{key} is {value.dtype} {list(value.shape)}, the model's "
                f"{own.dtype} {list(own.shape)}"
            ]
        if own.is_floating_point() and bool(torch.isfinite(own).all()):
            if not bool(torch.isfinite(value).all()):
                return [f"{field}.{key} holds a NaN or infinite value"]
    return []


def _finite_like(field: str, saved: Any, live: Mapping[str, Any]) -> list[str]:
    """A plain state (a scheduler's): the same keys, each value finite where the live one is."""
    if not isinstance(saved, Mapping) or set(saved) != set(live):
        return [f"{field} is not the run's {sorted(live)}"]
    bad = {
        k: saved[k]
        for k, v in live.items()
        if _number(v)
        and math.isfinite(v)
        and (not _number(saved[k]) or not math.isfinite(saved[k]))
    }
    return [f"{field} holds {bad}, not finite numbers"] if bad else []


def _rng_problem(rng: Any) -> str | None:
    """Why the saved generator states do not load (each tried, then the current ones put back)."""
    if not isinstance(rng, Mapping) or not {"python", "numpy", "torch"} <= set(rng):
        return "not the python, numpy and torch generator states"
    torch_state = rng["torch"]
    own = torch.get_rng_state()
    if not isinstance(torch_state, torch.Tensor) or torch_state.dtype != own.dtype:
        return "its torch state is not a byte tensor"
    if torch_state.shape != own.shape:
        return f"its torch state has shape {list(torch_state.shape)}, not {list(own.shape)}"
    python, numpy = random.getstate(), np.random.get_state()
    try:
        random.setstate(rng["python"])
        np.random.set_state(rng["numpy"])
    except (TypeError, ValueError, OverflowError) as err:
        return f"its python or numpy state does not load ({err})"
    finally:
        random.setstate(python)
        np.random.set_state(numpy)
    return None


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _count(value: Any) -> bool:
    """A whole count >= 0 (an ``int``, or a float holding one, as older files kept some)."""
    return (
        _number(value) and math.isfinite(value) and value == int(value) and 0 <= value < MAX_COUNT
    )
