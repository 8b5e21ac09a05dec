"""``make_dm_env`` / ``make_env``: build a task by name (dm_control ``SUITE`` style)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from dm_control.rl import control

from gentlerl.envs.assets import scene_xml
from gentlerl.envs.hand import CONTROL_TIMESTEP, Explore, Fragile, HandPhysics, Touch
from gentlerl.envs.torchrl_env import HandEnv

_TASKS = {"explore": Explore, "touch": Touch, "fragile": Fragile}
TASKS: tuple[str, ...] = tuple(_TASKS)


def make_dm_env(
    task: str = "touch", *, seed: int | None = None, time_limit: int = 200, **task_kwargs: Any
) -> control.Environment:
    """The plain dm_control environment of ``task`` (so dm_control's viewer and tools work).

    Args:
        task: one of :data:`TASKS`.
        seed: seeds the task's RandomState (block placement).
        time_limit: control steps (50 ms each) before truncation (default 200 = 10 s).
        **task_kwargs: the task's keyword arguments, e.g. ``force_threshold=5.0``,
            ``break_impact=3.0``, ``action_scale=0.05``, ``randomize_block=True``.
    """
    if task not in _TASKS:
        raise ValueError(f"unknown task {task!r}; expected one of {list(TASKS)}")
    if not (isinstance(time_limit, int | np.integer) and time_limit >= 1):
        raise ValueError(f"time_limit must be an integer >= 1 (control steps), got {time_limit!r}")
    physics = HandPhysics.from_xml_string(scene_xml())
    task_obj = _TASKS[task](random=np.random.RandomState(seed), **task_kwargs)
    n_sub_steps = int(round(CONTROL_TIMESTEP / physics.model.opt.timestep))
    return control.Environment(
        physics,
        task_obj,
        time_limit=time_limit * CONTROL_TIMESTEP - 1e-9,
        n_sub_steps=n_sub_steps,
    )


def make_env(
    task: str = "touch",
    *,
    seed: int | None = None,
    device: str | torch.device = "cpu",
    from_pixels: bool = False,
    **task_kwargs: Any,
) -> HandEnv:
    """The TorchRL env of ``task`` (passes ``torchrl.envs.utils.check_env_specs``)."""
    time_limit = task_kwargs.pop("time_limit", 200)
    dm_env = make_dm_env(task, seed=seed, time_limit=time_limit, **task_kwargs)
    env = HandEnv(dm_env, time_limit=time_limit, device=device, from_pixels=from_pixels)
    if seed is not None:
        env.set_seed(seed)
    return env
