"""What an env's specs say about the agent: its sizes (observation, action, the dynamics model's
feature groups), its episode length, and whether it writes what the reward transforms read."""

from __future__ import annotations

import torch
from torchrl.envs import CatTensors, EnvBase, Transform, TransformedEnv

from gentlerl import keys

#: What a run reads from every env step besides the variant's reward components (``success``
#: and ``broken`` may be absent: an episode is then judged by its return).
REQUIRED_ENV_KEYS = (keys.OBSERVATION,)


def episode_steps(env: EnvBase, default: int = 1000) -> int:
    """``env.time_limit`` (control steps per episode) where the env names one, else ``default``.

    Read without ``getattr`` on the env: a batched TorchRL env forwards unknown attributes to its
    workers, which recurses before they start.
    """
    limit = vars(env).get("time_limit")
    if limit is None and isinstance(getattr(type(env), "time_limit", None), property):
        limit = env.time_limit
    return default if limit is None else int(limit)


def check_env_keys(env: EnvBase, transform: Transform, reward_keys: list[str]) -> None:
    """One clear error if ``env`` + the reward ``transform`` do not produce what a run reads.

    That is :data:`REQUIRED_ENV_KEYS`, ``impact`` (``ImpactPenalty``, logged for every variant)
    and every reward component in ``reward_keys``.
    """
    try:
        transformed = TransformedEnv(env, transform.clone(), auto_unwrap=False)
        produced = set(transformed.full_reward_spec.keys(True, True)) | set(
            transformed.full_observation_spec.keys(True, True)
        )
    except KeyError as err:
        raise ValueError(
            f"the env does not produce {err} that the reward transforms read "
            f"(env observation keys: {sorted(map(str, env.full_observation_spec.keys(True, True)))})"
        ) from err
    wanted = [*REQUIRED_ENV_KEYS, keys.IMPACT, *reward_keys]
    missing = [k for k in wanted if k not in produced]
    if missing:
        raise ValueError(
            f"key(s) {missing} needed by the run are produced neither by the env nor by the "
            f"reward transforms (produced: {sorted(map(str, produced))})"
        )


def observation_sources(env: EnvBase, obs_key: str = keys.OBSERVATION) -> list[str]:
    """The entries a ``CatTensors`` of ``env`` concatenates into ``obs_key`` (as
    :func:`gentlerl.envs.external.adapt_env` appends it), else ``[]``."""
    transform = getattr(env, "transform", None)
    for t in transform if transform is not None else ():
        if isinstance(t, CatTensors) and list(t.out_keys) == [obs_key]:
            return [str(k) for k in t.in_keys]
    return []


def env_feature_shapes(env: EnvBase, obs_key: str = keys.OBSERVATION) -> dict[str, tuple[int, ...]]:
    """The dynamics model's feature groups (eq. 6) and their per-step shapes, for ``env``.

    The hand's joint positions, velocities and touch where the env writes them; else the
    entries that its ``obs_key`` concatenates (dm_control's finger: position, velocity, touch);
    else ``obs_key`` itself.
    """
    spec = env.observation_spec
    batch_dims = len(env.batch_size)
    features = [k for k in keys.DYNAMICS_FEATURES if k in spec.keys()]
    if keys.JOINT_POS not in features:
        features = observation_sources(env, obs_key) or features or [obs_key]
    return {k: tuple(spec[k].shape[batch_dims:]) for k in features}


def env_sizes(
    env: EnvBase, obs_key: str, force_key: str
) -> tuple[int, int, dict[str, tuple[int, ...]]]:
    """``(obs_dim, action_dim, feature_shapes)`` of ``env``, or an error naming the entry it lacks
    (``obs_key``, ``force_key``) and the entries it has, or a force not shaped
    ``[..., n_sites, n_channels]``."""
    spec = env.observation_spec
    present = sorted(map(str, spec.keys(True, True)))
    for name, key in (("obs_key", obs_key), ("force_key", force_key)):
        if key not in spec.keys(True, True):
            raise KeyError(
                f"IntrinsicRewards.from_env: {name}={key!r} is not in the env's observation "
                f"spec, which has {present}"
            )
    obs = spec[obs_key]
    if len(obs.shape) - len(env.batch_size) != 1 or not obs.dtype.is_floating_point:
        raise ValueError(
            f"IntrinsicRewards.from_env: {obs_key!r} must be a flat float vector [obs_dim], got "
            f"{tuple(obs.shape[len(env.batch_size) :])} {obs.dtype} (an image or a dict needs an "
            "encoder or CatTensors first)"
        )
    force_shape = spec[force_key].shape[len(env.batch_size) :]
    if len(force_shape) != 2 or 0 in force_shape:
        raise ValueError(
            f"IntrinsicRewards.from_env: {force_key!r} must be [n_sites >= 1, n_channels >= 1], "
            f"got {tuple(force_shape)} (UnsqueezeTransform(-1) adds a channel dim)"
        )
    for key in (obs_key, force_key):  # the models are float32
        if spec[key].dtype != torch.float32:
            raise ValueError(
                f"IntrinsicRewards.from_env: {key!r} must be float32, got {spec[key].dtype} "
                "(torchrl's DoubleToFloat casts an env's float64 entries)"
            )
    return spec[obs_key].shape[-1], env.action_spec.shape[-1], env_feature_shapes(env, obs_key)
