"""What an env's specs say about the agent's sizes: the dynamics model's feature groups."""

from __future__ import annotations

from torchrl.envs import CatTensors, EnvBase

from gentlerl import keys


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
