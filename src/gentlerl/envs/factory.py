"""``make_dm_env`` / ``make_env``: build a task by name from a dm_control-style ``SUITE``.

:data:`TASK_CLASSES` is the table of the hand tasks; ``SUITE`` and ``TASKS`` derive from it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from dm_control.utils import containers

from gentlerl.envs.assets import scene_xml
from gentlerl.envs.batched import BatchedHandEnv
from gentlerl.envs.environment import HandEnvironment
from gentlerl.envs.hand import (
    CONTROL_TIMESTEP,
    DEFAULT_REGIME,
    REGIMES,
    Explore,
    Fragile,
    HandPhysics,
    Touch,
)
from gentlerl.envs.task_names import RENAMED_KWARGS
from gentlerl.envs.torchrl_env import HandEnv

#: The hand tasks, by name: the one table :data:`SUITE`, :data:`TASKS` and
#: :class:`~gentlerl.envs.driver_env.DriverHandEnv` read.
TASK_CLASSES: dict[str, type[Explore]] = {"explore": Explore, "touch": Touch, "fragile": Fragile}


def _load(
    task_cls: type[Explore],
    time_limit: int,
    random: Any,
    regime: str = DEFAULT_REGIME,
    **task_kwargs: Any,
) -> HandEnvironment:
    for old in task_kwargs.keys() & RENAMED_KWARGS:
        raise TypeError(f"{old}= is now {RENAMED_KWARGS[old]}= (the hand's physics regime)")
    if regime not in REGIMES:
        raise ValueError(f"unknown regime {regime!r}; expected one of {list(REGIMES)}")
    task_kwargs = {**REGIMES[regime], **task_kwargs}
    actuator_gain = task_kwargs.pop("actuator_gain")
    if not (isinstance(time_limit, int | np.integer) and time_limit >= 1):
        raise ValueError(f"time_limit must be an integer >= 1 (control steps), got {time_limit!r}")
    if not (np.isfinite(actuator_gain) and actuator_gain > 0):
        raise ValueError(f"actuator_gain must be a finite number > 0, got {actuator_gain!r}")
    physics = HandPhysics.from_xml_string(scene_xml(actuator_gain=float(actuator_gain)))
    task = task_cls(random=random, **task_kwargs)
    n_sub_steps = int(round(CONTROL_TIMESTEP / physics.model.opt.timestep))
    # dm_control truncates once physics time >= time_limit; the epsilon makes that exactly
    # ``time_limit`` control steps despite float rounding.
    return HandEnvironment(
        physics, task, time_limit=time_limit * CONTROL_TIMESTEP - 1e-9, n_sub_steps=n_sub_steps
    )


def _suite_entry(name: str, task_cls: type[Explore]) -> Callable[..., HandEnvironment]:
    """The dm_control-style loader of ``task_cls``, named ``name`` (as ``SUITE`` keys it)."""

    def load(time_limit: int = 200, random: Any = None, **task_kwargs: Any) -> HandEnvironment:
        return _load(task_cls, time_limit, random, **task_kwargs)

    load.__name__ = load.__qualname__ = name
    load.__doc__ = task_cls.__doc__
    return load


def _make_suite() -> containers.TaggedTasks:
    """:data:`SUITE`: one loader per entry of :data:`TASK_CLASSES`, in its order."""
    suite = containers.TaggedTasks()
    for name, task_cls in TASK_CLASSES.items():
        suite.add()(_suite_entry(name, task_cls))
    return suite


SUITE = _make_suite()
TASKS: tuple[str, ...] = tuple(SUITE)


def make_dm_env(
    task: str = "touch", *, seed: int | None = None, **task_kwargs: Any
) -> HandEnvironment:
    """The plain dm_control environment of ``task`` (so dm_control's viewer and tools work).

    Args:
        task: one of :data:`TASKS`.
        seed: seeds the task's RandomState (block placement); same seed, same rollouts.
        **task_kwargs: ``time_limit`` (control steps of 50 ms before truncation, default 200)
            ``regime`` (the hand's physics regime, a name in :data:`~gentlerl.envs.hand.REGIMES`:
            ``"paper"``, the default, or ``"easy"``; ``calibration=``, its name before, is refused
            naming it), whose values (``action_scale``, ``actuator_gain``, ``block_gap``) single
            keyword arguments override, and the task's keyword arguments, e.g.
            ``force_threshold=5.0``, ``break_impact=3.0``, ``randomize_block=True``,
            ``block_range=0.005``.
    """
    if task not in SUITE:
        raise ValueError(f"unknown task {task!r}; expected one of {list(TASKS)}")
    return SUITE[task](random=np.random.RandomState(seed), **task_kwargs)


def make_env(
    task: str = "touch",
    *,
    seed: int | None = None,
    device: str | torch.device = "cpu",
    from_pixels: bool = False,
    num_envs: int | None = None,
    num_threads: int | None = None,
    **task_kwargs: Any,
) -> HandEnv | BatchedHandEnv:
    """The TorchRL env of ``task`` (passes ``torchrl.envs.utils.check_env_specs``).

    Same arguments as :func:`make_dm_env`; ``from_pixels`` adds an 84x84 RGB ``pixels``
    observation (needs an OpenGL backend, see :mod:`gentlerl.envs.rendering`).

    ``num_envs=None`` (default): one hand, a :class:`HandEnv` with batch size ``[]``. An integer:
    a :class:`BatchedHandEnv` with batch size ``[num_envs]`` stepping that many hands in this
    process, their physics on ``num_threads`` threads (default: ``min(num_envs, cores)``); hand
    ``i`` is seeded as TorchRL's ``ParallelEnv`` seeds worker ``i`` (hand 0 gets ``seed``).
    """
    if num_envs is None:
        if num_threads is not None:
            raise ValueError(f"num_threads={num_threads!r} needs num_envs (a batched env)")
        env = HandEnv(
            make_dm_env(task, seed=seed, **task_kwargs), device=device, from_pixels=from_pixels
        )
    else:
        if not (isinstance(num_envs, int | np.integer) and num_envs >= 1):
            raise ValueError(f"num_envs must be an integer >= 1 (hands), got {num_envs!r}")
        dm_envs = [make_dm_env(task, seed=seed, **task_kwargs) for _ in range(num_envs)]
        env = BatchedHandEnv(
            dm_envs, num_threads=num_threads, device=device, from_pixels=from_pixels
        )
    if seed is not None:
        env.set_seed(seed)
    return env


#: Arguments of :func:`make_env` that a training run sets itself (from its seed and collector).
_SET_BY_RUN = {"task", "seed", "num_envs", "num_threads", "random", "task_cls", "self"}


def _named_params(fn: Any) -> tuple[set[str], bool]:
    """``fn``'s named parameters, and whether it also takes ``**kwargs``."""
    params = inspect.signature(fn).parameters.values()
    named = {p.name for p in params if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
    return named, any(p.kind == p.VAR_KEYWORD for p in params)


def env_kwarg_names(task: str) -> list[str]:
    """The keyword arguments ``make_env(task, seed=..., **kwargs)`` accepts as ``kwargs`` (the
    regime's fields, ``make_env``'s and the task class's keywords) for config validation."""
    if task not in TASK_CLASSES:
        raise ValueError(f"unknown task {task!r}; expected one of {list(TASKS)}")
    names = _named_params(make_env)[0] | _named_params(_load)[0]
    names |= {key for fields in REGIMES.values() for key in fields}
    for cls in TASK_CLASSES[task].__mro__:
        if "__init__" in vars(cls):
            named, more = _named_params(cls.__init__)
            names |= named
            if not more:
                break
    return sorted(names - _SET_BY_RUN)
