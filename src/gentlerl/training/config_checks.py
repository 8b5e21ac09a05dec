"""Checks of :func:`~gentlerl.training.config.validate` beyond ranges: every value has its field's
type and is finite, and fields that must agree do (buffer vs batch, env keywords vs task).

Types come from the dataclass annotations, so a new field is checked without listing it here.
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Iterator
from typing import Any

from gentlerl.training.schema import GROUPS, TrainConfig


def _leaves(cfg: Any) -> Iterator[tuple[str, Any, Any]]:
    """``(name, annotation, value)`` of every leaf field of a ``TrainConfig``."""
    for name, hint in typing.get_type_hints(TrainConfig).items():
        if name not in GROUPS:
            yield name, hint, getattr(cfg, name)
    for group, cls in GROUPS.items():
        for name, hint in typing.get_type_hints(cls).items():
            yield f"{group}.{name}", hint, getattr(getattr(cfg, group), name)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _problem(name: str, hint: Any, value: Any) -> str | None:
    """Why ``value`` does not fit ``hint`` (or is not finite), or ``None``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        alternatives = [a for a in args if a is not type(None)]
        found = [_problem(name, a, value) for a in alternatives]
        return None if None in found else found[0]
    if hint is bool and not isinstance(value, bool):
        return f"{name}={value!r} must be true or false"
    if hint is int and not (isinstance(value, int) and not isinstance(value, bool)):
        return f"{name}={value!r} must be an integer"
    if hint is float and not (_is_number(value) and math.isfinite(value)):
        return f"{name}={value!r} must be a finite number"
    if hint is str and not isinstance(value, str):
        return f"{name}={value!r} must be a string"
    if origin is tuple:
        if not isinstance(value, tuple | list):
            return f"{name}={value!r} must be a list"
        element_hints = [args[0]] * len(value) if args[-1] is Ellipsis else list(args)
        if len(element_hints) != len(value):
            return f"{name}={list(value)} must have {len(element_hints)} values"
        for i, (element_hint, element) in enumerate(zip(element_hints, value, strict=True)):
            found = _problem(f"{name}[{i}]", element_hint, element)
            if found:
                return found
    if origin is dict and not isinstance(value, dict):
        return f"{name}={value!r} must be a mapping"
    return None


def type_problems(cfg: Any) -> list[str]:
    """One line per field whose value is of the wrong type or not finite; ``resume`` choices."""
    problems = [p for leaf in _leaves(cfg) if (p := _problem(*leaf))]
    # true: continue (needs the checkpoint); false: start (refuses an existing run); auto: either.
    if not (isinstance(cfg.resume, bool) or cfg.resume == "auto"):
        problems.append(f"resume={cfg.resume!r} must be true, false or 'auto'")
    return problems


def consistency_problems(cfg: Any) -> list[str]:
    """Seeds, buffer vs batch, and env keywords the task accepts (listing the valid ones)."""
    from gentlerl.envs.factory import TASKS, env_kwarg_names

    problems = []
    if not 0 <= cfg.seed < 2**32:
        problems.append(f"seed={cfg.seed} must be in [0, 2**32) (numpy's seed range)")
    if not cfg.run_dir.strip():
        problems.append(f"run_dir={cfg.run_dir!r} must name a directory (empty: the working one)")
    replay = cfg.replay
    if replay.buffer_size < replay.batch_size:
        problems.append(
            f"replay.buffer_size={replay.buffer_size} must be >= replay.batch_size="
            f"{replay.batch_size} (no update could ever sample a batch)"
        )
    if cfg.task in TASKS and cfg.env.name is None:  # else kwargs go to the external env
        valid = env_kwarg_names(cfg.task)
        unknown = sorted(set(cfg.env.kwargs) - set(valid))
        if unknown:
            problems.append(
                f"env.kwargs {unknown} are not keywords of task {cfg.task!r}; valid: {valid}"
            )
    return problems
