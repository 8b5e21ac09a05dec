"""TorchRL envs that someone else wrote, made ready for the gentleness rewards and the loop.

``make_external_env("dm_control:finger-spin")`` is TorchRL's ``DMControlEnv("finger", "spin")``
with three transforms appended (:func:`adapt_env`):

1. ``DoubleToFloat``: dm_control writes float64 observations, rewards and actions; the agent's
   networks are float32, so everything is cast once, at the env's boundary.
2. a *force adapter* (:data:`FORCE_ADAPTERS`): the transforms that bring the env's contact
   reading to ``[..., n_sites, n_channels]`` newtons under ``force_key``, what ``ImpactPenalty``
   reads. dm_control's touch sensors are written as ``log1p`` of the reading
   (``suite/finger.py``: ``np.log1p(touchtop, touchbottom)``), so ``dm_control_touch`` undoes it
   with ``expm1`` and adds a channel dim: finger's ``touch`` ``[2]`` -> ``force`` ``[2, 1]``.
3. ``CatTensors`` of the env's observation keys (finger: ``position`` [4], ``velocity`` [3],
   ``touch`` [2]) into ``observation`` [9], the agent's input; the entries are kept, so the
   dynamics model can predict each group.

Such an env has no ``success`` / ``broken``: the loop judges it by its return.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch
from torchrl.envs import (
    CatTensors,
    DoubleToFloat,
    EnvBase,
    Transform,
    TransformedEnv,
    UnaryTransform,
    UnsqueezeTransform,
)

from gentlerl import keys

#: Where the force adapter writes by default.
FORCE = "force"


@dataclass(frozen=True)
class ForceAdapter:
    """How to get newtons ``[..., n_sites, n_channels]`` out of an env's contact reading.

    Attributes:
        source: the env's entry it reads.
        build: ``(source, force_key) -> transforms`` writing ``force_key``.
        help: one line for ``--help`` and errors.
    """

    source: str
    build: Callable[[str, str], list[Transform]]
    help: str


def _log1p_touch(source: str, force_key: str) -> list[Transform]:
    return [
        UnaryTransform(in_keys=[source], out_keys=[force_key], fn=torch.expm1),
        UnsqueezeTransform(-1, in_keys=[force_key]),
    ]


def _channels(source: str, force_key: str) -> list[Transform]:
    return [UnsqueezeTransform(-1, in_keys=[source], out_keys=[force_key])]


#: Named force adapters (``env.force_adapter``); ``none``: the env writes ``force_key`` itself.
FORCE_ADAPTERS: dict[str, ForceAdapter | None] = {
    "dm_control_touch": ForceAdapter(
        keys.TOUCH, _log1p_touch, "dm_control touch sensors: expm1 of touch [n] -> [n, 1] N"
    ),
    "touch_newtons": ForceAdapter(
        keys.TOUCH, _channels, "touch sensors already in N: touch [n] -> [n, 1] N"
    ),
    "none": None,
}

#: Env sources of ``env.name="<source>:<spec>"``: how to build the raw TorchRL env, and the
#: force adapter it gets when ``env.force_adapter`` is null.
SOURCES = {"dm_control": "dm_control_touch"}


def parse_name(name: str) -> tuple[str, str, str]:
    """``"dm_control:finger-spin"`` -> ``("dm_control", "finger", "spin")``; a ``ValueError``
    saying the expected form otherwise."""
    source, _, spec = name.partition(":")
    domain, _, task = spec.partition("-")
    if source not in SOURCES or not domain or not task:
        raise ValueError(
            f"env.name={name!r} must read '<source>:<domain>-<task>' with source one of "
            f"{sorted(SOURCES)}, e.g. 'dm_control:finger-spin'"
        )
    return source, domain, task


def check_name(name: str) -> list[str]:
    """Problems with ``env.name`` for config validation: its form, and that dm_control has it."""
    try:
        _, domain, task = parse_name(name)
    except ValueError as err:
        return [str(err)]
    from dm_control import suite

    if (domain, task) not in suite.ALL_TASKS:
        near = sorted(f"{d}-{t}" for d, t in suite.ALL_TASKS if d == domain) or sorted(
            {d for d, _ in suite.ALL_TASKS}
        )
        return [f"env.name={name!r}: dm_control has no task {domain}-{task}; known: {near}"]
    return []


def kwargs_problems(kwargs: dict) -> list[str]:
    """Problems with the ``DMControlEnv`` keywords of ``env.kwargs`` that it would only meet
    later and obscurely: ``frame_skip`` (an integer >= 1; 0 fails at the first step) and
    ``device`` (one this machine's torch has)."""
    problems = []
    skip = kwargs.get("frame_skip", 1)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 1:
        problems.append(f"env.kwargs.frame_skip={skip!r} must be an integer >= 1")
    if "device" in kwargs:
        device = kwargs["device"]
        try:
            parsed = torch.device(device)
        except (RuntimeError, TypeError):
            return [*problems, f"env.kwargs.device={device!r} is not a torch device (cpu, cuda:0)"]
        count = torch.cuda.device_count() if parsed.type == "cuda" else None
        if count is not None and (parsed.index or 0) >= count:
            problems.append(
                f"env.kwargs.device={device!r}: this machine's torch has {count} CUDA device(s)"
            )
        elif parsed.type not in ("cpu", "cuda"):
            problems.append(f"env.kwargs.device={device!r} must be cpu or cuda[:N]")
    return problems


def adapt_env(
    env: EnvBase,
    *,
    force_adapter: str = "dm_control_touch",
    force_key: str = FORCE,
    observation_keys: Sequence[str] | None = None,
    force_scale: float = 1.0,
) -> TransformedEnv:
    """``env`` with float32 entries, ``force_key`` in newtons and a flat ``observation``.

    Args:
        env: any TorchRL env.
        force_adapter: a name in :data:`FORCE_ADAPTERS`.
        force_key: where the force lands (``none`` adapter: the env's own force entry).
        observation_keys: what ``observation`` concatenates (default: every observation entry
            of ``env`` but pixels, in spec order); one key named ``observation`` is kept as it is.
        force_scale: multiplies the force the rewards read (the unit the penalty's lambda is
            in: finger-spin's contacts reach hundreds of newtons, ``0.01`` reads them in
            hundreds); the observation keeps the env's own reading, while impacts, penalties
            and every reported max impact are in the scaled unit (N x ``force_scale``).
    """
    if not (isinstance(force_scale, int | float) and 0 < force_scale < float("inf")):
        raise ValueError(f"force_scale must be a finite number > 0, got {force_scale!r}")
    if force_adapter not in FORCE_ADAPTERS:
        raise ValueError(
            f"unknown force adapter {force_adapter!r}; expected one of {sorted(FORCE_ADAPTERS)}"
        )
    spec = env.observation_spec
    if observation_keys is None:
        observation_keys = [k for k in spec.keys() if k != keys.PIXELS]
    missing = [k for k in observation_keys if k not in spec.keys()]
    if missing:
        raise ValueError(
            f"observation key(s) {missing} (env.observation_keys) are not in the env's "
            f"observation spec {sorted(map(str, spec.keys()))}"
        )
    transforms: list[Transform] = [DoubleToFloat()]
    adapter = FORCE_ADAPTERS[force_adapter]
    if adapter is not None:
        if adapter.source not in spec.keys():
            raise ValueError(
                f"force adapter {force_adapter!r} (env.force_adapter) reads {adapter.source!r}, "
                f"which the env lacks (observation keys {sorted(map(str, spec.keys()))}); see "
                "FORCE_ADAPTERS"
            )
        transforms += adapter.build(adapter.source, force_key)
    if list(observation_keys) != [keys.OBSERVATION]:
        transforms.append(
            CatTensors(list(observation_keys), keys.OBSERVATION, del_keys=False, sort=False)
        )
    out = ExternalEnv(env)
    for transform in transforms:
        out.append_transform(transform)
    _check_force_entry(out, force_key, force_adapter)
    if force_scale != 1.0:  # after the observation is built: it keeps the env's own reading
        out.append_transform(
            UnaryTransform(in_keys=[force_key], out_keys=[force_key], fn=_Scale(force_scale))
        )
    return out


def _check_force_entry(env: EnvBase, force_key: str, force_adapter: str) -> None:
    """A one-line error unless ``env`` writes ``force_key`` shaped ``[n_sites, n_channels]``."""
    spec = env.observation_spec
    if force_key not in spec.keys(True):
        raise ValueError(
            f"force key {force_key!r} (env.force_key) is not written by the env nor by adapter "
            f"{force_adapter!r} (observation keys {sorted(map(str, spec.keys()))})"
        )
    shape = list(spec[force_key].shape[len(env.batch_size) :])
    if len(shape) < 2:
        raise ValueError(
            f"force key {force_key!r} (env.force_key) has shape {shape}, not the [n_sites, "
            f"n_channels] newtons the rewards read (env.force_adapter={force_adapter!r}; "
            "touch_newtons adds the channel dim of a reading in N)"
        )


class _Scale:
    """``x * factor``, picklable (a collector's worker process rebuilds the env)."""

    def __init__(self, factor: float) -> None:
        self.factor = float(factor)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.factor


class ExternalEnv(TransformedEnv):
    """A ``TransformedEnv`` that names its episode length (``time_limit``, control steps) where
    the base env knows it (dm_control's step limit), as gentlerl's hand env does."""

    @property
    def time_limit(self) -> int | None:
        dm_env = getattr(self.base_env, "_env", None)
        limit = getattr(dm_env, "_step_limit", None)
        return None if limit is None or limit == float("inf") else int(limit)


def make_external_env(
    name: str,
    *,
    seed: int | None = None,
    force_adapter: str | None = None,
    force_key: str | None = None,
    observation_keys: Sequence[str] | None = None,
    force_scale: float = 1.0,
    **kwargs,
) -> TransformedEnv:
    """The TorchRL env ``name`` (``"dm_control:<domain>-<task>"``) through :func:`adapt_env`.

    ``force_adapter`` null: the source's (:data:`SOURCES`); ``force_key`` null: ``force``.
    ``kwargs`` go to ``DMControlEnv`` (e.g. ``frame_skip``, ``from_pixels``).
    """
    source, domain, task = parse_name(name)
    from torchrl.envs import DMControlEnv

    env = adapt_env(
        DMControlEnv(domain, task, **kwargs),
        force_adapter=force_adapter or SOURCES[source],
        force_key=force_key or FORCE,
        observation_keys=observation_keys,
        force_scale=force_scale,
    )
    if seed is not None:
        env.set_seed(seed)
    return env
