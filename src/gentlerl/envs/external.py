"""TorchRL envs that someone else wrote, made ready for the gentleness rewards and the loop.

``make_external_env("dm_control:finger-spin")`` is TorchRL's ``DMControlEnv("finger", "spin")``
(``"gym:Hopper-v5"``: ``GymEnv("Hopper-v5")``, any Gymnasium id;
``"manipulation:lift_brick_features"``: a dm_control manipulation env, :class:`ComposerEnv`) with
three transforms appended (:func:`adapt_env`):

1. ``DoubleToFloat``: dm_control writes float64 observations, rewards and actions; the agent's
   networks are float32, so everything is cast once, at the env's boundary.
2. a *force adapter* (:data:`FORCE_ADAPTERS`): the transforms that bring the env's contact
   reading to ``[..., n_sites, n_channels]`` newtons under ``force_key``, what ``ImpactPenalty``
   reads. dm_control's touch sensors are written as ``log1p`` of the reading
   (``suite/finger.py``: ``np.log1p(touchtop, touchbottom)``), so ``dm_control_touch`` undoes it
   with ``expm1`` and adds a channel dim: finger's ``touch`` ``[2]`` -> ``force`` ``[2, 1]``.
   Envs without touch sensors get ``contacts`` (:class:`~gentlerl.envs.contacts.ContactForces`):
   MuJoCo's contact forces summed per named group of bodies or geoms (``force_groups``; walker's
   feet by default, :data:`~gentlerl.envs.contacts.CONTACT_GROUPS`).
3. ``CatTensors`` of the env's observation keys (finger: ``position`` [4], ``velocity`` [3],
   ``touch`` [2]) into ``observation`` [9], the agent's input; the entries are kept, so the
   dynamics model can predict each group (an entry of rank > 1, a composer observable
   ``[1, n]``, is flattened first).

Such an env has no ``success`` / ``broken``: the loop judges it by its return.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import torch
from torchrl.envs import (
    CatTensors,
    DMControlWrapper,
    DoubleToFloat,
    EnvBase,
    FlattenObservation,
    Transform,
    TransformedEnv,
    UnaryTransform,
    UnsqueezeTransform,
)

from gentlerl import keys

if TYPE_CHECKING:
    import mujoco

#: Where the force adapter writes by default.
FORCE = "force"


@dataclass(frozen=True)
class ForceAdapter:
    """How to get newtons ``[..., n_sites, n_channels]`` out of an env's contact reading.

    Attributes:
        source: the env's entry it reads (``None``: it reads the simulator).
        build: ``(source, force_key) -> transforms`` writing ``force_key``; with ``groups``,
            ``(source, force_key, groups)``.
        help: one line for ``--help`` and errors.
        groups: it takes ``force_groups`` (group name -> body or geom names).
    """

    source: str | None
    build: Callable[..., list[Transform]]
    help: str
    groups: bool = False


def _log1p_touch(source: str, force_key: str) -> list[Transform]:
    return [
        UnaryTransform(in_keys=[source], out_keys=[force_key], fn=torch.expm1),
        UnsqueezeTransform(-1, in_keys=[force_key]),
    ]


def _channels(source: str, force_key: str) -> list[Transform]:
    return [UnsqueezeTransform(-1, in_keys=[source], out_keys=[force_key])]


def _contacts(source: None, force_key: str, groups: Mapping[str, Sequence[str]]) -> list[Transform]:
    from gentlerl.envs.contacts import ContactForces

    return [ContactForces(groups, out_key=force_key)]


#: Named force adapters (``env.force_adapter``); ``none``: the env writes ``force_key`` itself.
FORCE_ADAPTERS: dict[str, ForceAdapter | None] = {
    "dm_control_touch": ForceAdapter(
        keys.TOUCH, _log1p_touch, "dm_control touch sensors: expm1 of touch [n] -> [n, 1] N"
    ),
    "touch_newtons": ForceAdapter(
        keys.TOUCH, _channels, "touch sensors already in N: touch [n] -> [n, 1] N"
    ),
    "contacts": ForceAdapter(
        None,
        _contacts,
        "MuJoCo's contact normal forces summed per group of bodies or geoms (env.force_groups) "
        "-> [n_groups, 1] N",
        groups=True,
    ),
    "none": None,
}

#: Env sources of ``env.name="<source>:<spec>"``: the form of ``spec``. The raw TorchRL env is
#: ``DMControlEnv(domain, task)`` or ``GymEnv(id)``; its force adapter when ``env.force_adapter``
#: is null is :func:`default_adapter`'s.
SOURCES = {
    "dm_control": "'dm_control:<domain>-<task>', e.g. 'dm_control:finger-spin'",
    "gym": "'gym:<Gymnasium id>', e.g. 'gym:Hopper-v5'",
    "manipulation": "'manipulation:<name>' (dm_control.manipulation), e.g. "
    "'manipulation:lift_brick_features'",
}


def parse_name(name: str) -> tuple[str, str]:
    """``"dm_control:finger-spin"`` -> ``("dm_control", "finger-spin")``, ``"gym:Hopper-v5"`` ->
    ``("gym", "Hopper-v5")``; a ``ValueError`` saying the expected form otherwise."""
    source, _, spec = name.partition(":")
    domain, _, task = spec.partition("-")
    if source not in SOURCES or not domain or not (task or source == "manipulation"):
        forms = " or ".join(SOURCES.values())
        raise ValueError(f"env.name={name!r} must read {forms}")
    return source, spec


def check_name(name: str) -> list[str]:
    """Problems with ``env.name`` for config validation: its form, and that dm_control (or
    Gymnasium's registry) has it."""
    try:
        source, spec = parse_name(name)
    except ValueError as err:
        return [str(err)]
    if source == "manipulation":
        from dm_control import manipulation

        if spec in manipulation.ALL:
            return []
        near = sorted(n for n in manipulation.ALL if n.endswith("_features"))
        return [f"env.name={name!r}: dm_control.manipulation has no env {spec}; known: {near}"]
    if source == "gym":
        import gymnasium

        ids = list(gymnasium.envs.registry)
        if spec in ids:
            return []
        stem = spec.rpartition("-v")[0] or spec
        near = sorted(i for i in ids if i.rpartition("-v")[0] == stem) or sorted(
            i for i in ids if "mujoco" in str(gymnasium.envs.registry[i].entry_point)
        )
        return [f"env.name={name!r}: Gymnasium has no env {spec}; known: {near}"]
    from dm_control import suite

    domain, _, task = spec.partition("-")
    if (domain, task) not in suite.ALL_TASKS:
        near = sorted(f"{d}-{t}" for d, t in suite.ALL_TASKS if d == domain) or sorted(
            {d for d, _ in suite.ALL_TASKS}
        )
        return [f"env.name={name!r}: dm_control has no task {domain}-{task}; known: {near}"]
    return []


def default_adapter(name: str, env: EnvBase) -> str:
    """The force adapter of ``env`` (the raw env of ``name``) when ``env.force_adapter`` is null:
    ``dm_control_touch`` where a dm_control env observes ``touch`` (finger, hopper), else
    ``contacts`` (walker, cheetah, ball_in_cup; every Gymnasium env)."""
    if name.startswith("dm_control:") and keys.TOUCH in env.observation_spec.keys():
        return "dm_control_touch"
    return "contacts"


def groups_of(name: str, force_groups: Mapping[str, Sequence[str]] | None) -> dict | None:
    """``force_groups``, else the env's default (:data:`~gentlerl.envs.contacts.CONTACT_GROUPS`),
    else ``None``."""
    if force_groups is not None:
        return dict(force_groups)
    from gentlerl.envs.contacts import default_groups

    return default_groups(name)


@lru_cache(maxsize=8)
def mujoco_model(name: str) -> mujoco.MjModel:
    """The ``MjModel`` of the external env ``name`` (built once per name), to check the names
    of ``env.force_groups`` against before a run starts."""
    source, spec = parse_name(name)
    if source == "gym":
        import gymnasium

        env = gymnasium.make(spec)
        try:
            model = getattr(env.unwrapped, "model", None)
        finally:
            env.close()
        if model is None:
            raise TypeError(f"{spec} is no MuJoCo env")
        return model
    if source == "manipulation":  # composer: imported only where asked (its imports are heavy)
        from dm_control import manipulation

        env = manipulation.load(spec)
    else:
        from dm_control import suite

        domain, _, task = spec.partition("-")
        env = suite.load(domain, task)
    return copy.deepcopy(env.physics.model.ptr)  # the env's own dies with it (a weak proxy)


def group_problems(
    name: str, force_adapter: str | None, force_groups: Mapping[str, Sequence[str]] | None
) -> list[str]:
    """Problems with ``env.force_groups`` for config validation: given to an adapter that takes
    none, missing where ``contacts`` reads an env without default groups (named, or the default
    of an env without touch sensors), a name the model lacks (the message lists its bodies).
    The env's model is loaded (once per name) only where groups are to be checked."""
    adapter = FORCE_ADAPTERS.get(force_adapter) if force_adapter is not None else None
    if force_adapter is not None and not (adapter is not None and adapter.groups):
        if force_groups is not None:
            return [
                f"env.force_groups applies to the contacts adapter, not to "
                f"env.force_adapter={force_adapter!r}"
            ]
        return []
    groups = groups_of(name, force_groups)
    if force_adapter is None and groups is not None and force_groups is None:
        return []  # the default groups of a known env
    try:
        model = mujoco_model(name)
    except Exception as err:  # the env's own failure (a missing extra, a bad model)
        return [f"env.force_adapter=contacts reads MuJoCo's contacts; {name}: {err}"]
    from gentlerl.envs.contacts import resolve_groups

    if force_adapter is None and force_groups is None and _has_touch(name, model):
        return []  # dm_control_touch, the default of a dm_control env with touch sensors
    if groups is None:
        return [f"env.force_adapter=contacts: {name} has no default groups; {_groups_hint(model)}"]
    try:
        resolve_groups(model, groups)
    except ValueError as err:
        return [f"env.force_groups: {err}"]
    return []


def _has_touch(name: str, model: mujoco.MjModel) -> bool:
    """Whether the dm_control env ``name`` has touch sensors (:func:`default_adapter` then
    picks ``dm_control_touch``), read from its model before the env is built."""
    import mujoco

    touch = int(mujoco.mjtSensor.mjSENS_TOUCH)
    return name.startswith("dm_control:") and bool((model.sensor_type == touch).any())


def _groups_hint(model: mujoco.MjModel) -> str:
    import mujoco

    bodies = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(model.nbody)]
    return f"set env.force_groups={{GROUP: [BODY, ...]}} (bodies: {[b for b in bodies if b]})"


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
    force_groups: Mapping[str, Sequence[str]] | None = None,
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
        force_groups: the ``contacts`` adapter's force sites, group name -> body or geom names
            (:func:`~gentlerl.envs.contacts.resolve_groups`).
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
    if force_groups is not None and not (adapter is not None and adapter.groups):
        raise ValueError(
            f"force groups (env.force_groups) apply to the contacts adapter, not to "
            f"{force_adapter!r} (env.force_adapter)"
        )
    if adapter is not None:
        if adapter.source is not None and adapter.source not in spec.keys():
            raise ValueError(
                f"force adapter {force_adapter!r} (env.force_adapter) reads {adapter.source!r}, "
                f"which the env lacks (observation keys {sorted(map(str, spec.keys()))}); see "
                "FORCE_ADAPTERS (contacts reads MuJoCo's contact forces)"
            )
        if adapter.groups:
            if force_groups is None:
                from gentlerl.envs.contacts import mujoco_handles

                raise ValueError(
                    f"force adapter {force_adapter!r} (env.force_adapter) needs force groups; "
                    + _groups_hint(mujoco_handles(env)[0])
                )
            transforms += adapter.build(adapter.source, force_key, force_groups)
        else:
            transforms += adapter.build(adapter.source, force_key)
    if list(observation_keys) != [keys.OBSERVATION]:
        by_rank: dict[int, list] = {}
        for key in observation_keys:  # composer observables are [1, n] or [1, n, m]: flat
            rank = len(spec[key].shape) - len(env.batch_size)
            if rank > 1:
                by_rank.setdefault(rank, []).append(key)
        transforms += [
            FlattenObservation(-rank, -1, in_keys=ranked) for rank, ranked in by_rank.items()
        ]
        transforms.append(
            CatTensors(list(observation_keys), keys.OBSERVATION, del_keys=False, sort=False)
        )
    out = ExternalEnv(env)
    for transform in transforms:
        out.append_transform(transform)
        if hasattr(transform, "bind"):  # names resolved against the env's model now
            transform.bind()
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
        raw = getattr(self.base_env, "_env", None)
        limit = getattr(raw, "_step_limit", None)  # dm_control
        if limit is None and isinstance(self.base_env, ComposerEnv):  # seconds
            seconds = raw._time_limit
            limit = round(seconds / raw.control_timestep()) if seconds != float("inf") else None
        elif limit is None:  # Gymnasium's TimeLimit
            limit = getattr(getattr(raw, "spec", None), "max_episode_steps", None)
        return None if limit is None or limit == float("inf") else int(limit)


class ComposerEnv(DMControlWrapper):
    """TorchRL's ``DMControlWrapper`` around a dm_control *composer* env
    (``dm_control.manipulation``), which TorchRL refuses by type (it takes suite envs only);
    seeded through the env's own random state, which the composer hands to its task at each
    episode."""

    def _check_kwargs(self, kwargs: dict) -> None:
        from dm_control import composer

        if not isinstance(kwargs.get("env"), composer.Environment):
            raise TypeError("ComposerEnv wraps a dm_control composer.Environment")

    def _set_seed(self, seed: int | None) -> None:
        if seed is not None:
            self._env.random_state.seed(seed)
            self.reset()


def make_external_env(
    name: str,
    *,
    seed: int | None = None,
    force_adapter: str | None = None,
    force_key: str | None = None,
    observation_keys: Sequence[str] | None = None,
    force_scale: float = 1.0,
    force_groups: Mapping[str, Sequence[str]] | None = None,
    **kwargs,
) -> TransformedEnv:
    """The TorchRL env ``name`` (``"dm_control:<domain>-<task>"``, ``"gym:<id>"``) through
    :func:`adapt_env`.

    ``force_adapter`` null: ``contacts`` where ``force_groups`` is given, else
    :func:`default_adapter`'s; ``force_key`` null: ``force``;
    ``force_groups`` null (``contacts``): the env's :data:`~gentlerl.envs.contacts.CONTACT_GROUPS`.
    ``kwargs`` go to ``DMControlEnv`` / ``GymEnv`` (e.g. ``frame_skip``, ``from_pixels``).
    """
    source, spec = parse_name(name)
    if source == "gym":
        from torchrl.envs import GymEnv

        raw = GymEnv(spec, **kwargs)
    elif source == "manipulation":
        from dm_control import manipulation

        raw = ComposerEnv(manipulation.load(spec), **kwargs)
    else:
        from torchrl.envs import DMControlEnv

        domain, _, task = spec.partition("-")
        raw = DMControlEnv(domain, task, **kwargs)
    if force_adapter is None:  # groups named: their adapter
        force_adapter = "contacts" if force_groups is not None else default_adapter(name, raw)
    adapter = FORCE_ADAPTERS.get(force_adapter)
    if adapter is not None and adapter.groups:
        force_groups = groups_of(name, force_groups)
    env = adapt_env(
        raw,
        force_adapter=force_adapter,
        force_key=force_key or FORCE,
        observation_keys=observation_keys,
        force_scale=force_scale,
        force_groups=force_groups,
    )
    if seed is not None:
        env.set_seed(seed)
    return env
