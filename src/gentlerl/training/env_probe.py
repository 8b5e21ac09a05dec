"""The run's env built and stepped once, before anything is written: the agent is sized from it,
and an env setting it cannot run with is named in one line (not met later, in a library's terms,
once the run directory and its lock exist)."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING

from torchrl.envs import EnvBase

from gentlerl import keys

if TYPE_CHECKING:
    from gentlerl.training.config import TrainConfig


def probe_env(cfg: TrainConfig, env_factory: Callable[[], EnvBase]) -> EnvBase:
    """``env_factory()``, reset and stepped once with a zero action, for the run ``cfg``: the env
    :func:`~gentlerl.training.builders.make_agent` sizes the agent from (the caller closes it).

    Raises:
        ValueError: the env cannot be built or cannot step; the message names the env settings
            (``env.kwargs.NAME`` when the env refused that keyword) and the env's own error.
    """
    try:
        env = env_factory()
    except Exception as err:
        raise ValueError(f"{_settings(cfg, err)}: cannot build the env ({_reason(err)})") from err
    try:
        td = env.reset()
        env.step(td.set(keys.ACTION, env.full_action_spec[keys.ACTION].zero()))
    except Exception as err:
        env.close()
        raise ValueError(f"{_settings(cfg, err)}: the env cannot step ({_reason(err)})") from err
    return env


def _settings(cfg: TrainConfig, err: Exception) -> str:
    """The env settings ``err`` is about: ``env.kwargs.NAME=value`` for a keyword the env does
    not take, else the env (``env.name`` or ``task``) with its ``env.kwargs``."""
    kwargs = cfg.env.kwargs
    unexpected = re.search(r"unexpected keyword argument '(\w+)'", str(err))
    if unexpected and unexpected[1] in kwargs:
        return f"env.kwargs.{unexpected[1]}={kwargs[unexpected[1]]!r} is not a keyword of the env"
    env = f"env.name={cfg.env.name!r}" if cfg.env.name is not None else f"task={cfg.task!r}"
    return f"{env} with env.kwargs={kwargs}" if kwargs else env


def _reason(err: Exception) -> str:
    """``err`` in one line: a ``ValueError``'s message as it is, anything else with its type."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    message = lines[0] if lines else ""
    return message if type(err) is ValueError else f"{type(err).__name__}: {message}"
