"""Every hyper-parameter of a run, in groups (:mod:`~gentlerl.training.schema`); presets;
up-front validation.

Defaults are the ``cpu`` scale; :data:`~gentlerl.training.presets.SCALES` holds the presets,
applied under user overrides by :func:`make_config`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from gentlerl.training.config_checks import consistency_problems, type_problems
from gentlerl.training.presets import SCALES
from gentlerl.training.schema import (
    COLLECTORS,
    GROUPS,
    WANDB_MODES,
    CollectorConfig,
    EnvConfig,
    GentlenessConfig,
    LearnerConfig,
    LoggingConfig,
    NetworkConfig,
    ReplayConfig,
    TrainConfig,
    get,
    iter_fields,
)

__all__ = [
    "COLLECTORS",
    "GROUPS",
    "SCALES",
    "WANDB_MODES",
    "CollectorConfig",
    "EnvConfig",
    "GentlenessConfig",
    "LearnerConfig",
    "LoggingConfig",
    "NetworkConfig",
    "ReplayConfig",
    "TrainConfig",
    "get",
    "group_flat_config",
    "iter_fields",
    "make_config",
    "validate",
]


def _merge(base: dict[str, Any], update: dict[str, Any], where: str = "") -> None:
    """Merge ``update`` into ``base`` in place; unknown names raise (listing the valid ones)."""
    for name, value in update.items():
        if name not in base:
            raise ValueError(
                f"unknown config field {where}{name!r}; valid fields: {sorted(base)}"
                if where
                else f"unknown config field(s) [{name!r}]; valid fields: {sorted(base)}"
            )
        if isinstance(base[name], dict) and name in GROUPS and not where:
            if not isinstance(value, dict):
                raise ValueError(f"config group {name!r} takes a mapping, got {value!r}")
            _merge(base[name], value, f"{name}.")
        else:
            base[name] = value


def make_config(scale: str = "cpu", **overrides: Any) -> TrainConfig:
    """The ``scale`` preset with ``overrides`` on top, validated.

    Overrides are top-level fields or groups given as (partial) mappings:
    ``make_config("paper", seed=1, replay={"batch_size": 64})``.
    """
    cfg = preset_config(scale, **overrides)
    validate(cfg)
    return cfg


def preset_config(scale: str = "cpu", **overrides: Any) -> TrainConfig:
    """:func:`make_config` without :func:`validate` (which looks up the env's task names, so
    imports the environments): for tools that only read sizes, like the learner benchmark."""
    if scale not in SCALES:
        raise ValueError(f"unknown scale {scale!r}; expected one of {sorted(SCALES)}")
    values = TrainConfig().to_dict()
    _merge(values, SCALES[scale])
    _merge(values, {**overrides, "scale": scale})
    groups = {}
    for name, cls in GROUPS.items():
        group = dict(values.pop(name))
        for f in dataclasses.fields(cls):
            if isinstance(f.default, tuple) and group[f.name] is not None:
                group[f.name] = tuple(group[f.name])
        groups[name] = cls(**group)
    return TrainConfig(**values, **groups)


#: Flat field names of configs saved before the grouping whose grouped name is not the same name.
_RENAMED = {"collector": ("collector", "kind"), "env_kwargs": ("env", "kwargs")}


def group_flat_config(values: dict[str, Any]) -> dict[str, Any]:
    """A config saved before the fields were grouped (older checkpoints), as :func:`make_config`
    takes it: each flat field moved into the group that holds that name now.

    ``penalty_v_max`` (the penalty head's top, null for none) becomes ``network.bounded_support``
    (null: false, else true). A name no group holds stays at the top level, where
    :func:`make_config` reports it. A field added since the config was saved and listed in
    :data:`_BEFORE` gets the value that reproduces what that run trained (not today's default).
    """
    if all(isinstance(values.get(group), dict) for group in GROUPS):
        return _with_earlier_behaviour(values)
    owner = {f.name: (g, f.name) for g, cls in GROUPS.items() for f in dataclasses.fields(cls)}
    owner.update(_RENAMED)
    grouped: dict[str, Any] = {}
    for name, value in values.items():
        if name == "penalty_v_max":
            name, value = "bounded_support", value is not None
        if name in owner:
            group, field = owner[name]
            grouped.setdefault(group, {})[field] = value
        else:
            grouped[name] = value
    return _with_earlier_behaviour(grouped)


#: Fields whose default changed the method, with the value that configs saved before them ran.
_BEFORE = {
    ("network", "dense_reward_bound"): None,  # one shared [v_min, v_max] for every head
    ("gentleness", "recompute_surprise"): False,  # r^sp stored at collection
    ("gentleness", "dynamics_surprise_scale"): 1.0,  # r^s as eq. 6 writes it
}


def _with_earlier_behaviour(grouped: dict[str, Any]) -> dict[str, Any]:
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in grouped.items()}
    for (group, name), value in _BEFORE.items():
        if isinstance(out.get(group), dict):  # a group the saved config has, without the field
            out[group].setdefault(name, value)
    return out


_POSITIVE = (
    "collector.total_frames collector.frames_per_batch collector.num_workers "
    "collector.weight_sync_every "
    "replay.batch_size "
    "replay.buffer_size replay.n_steps network.num_atoms learner.target_update_period "
    "gentleness.dynamics_target_period gentleness.penalty_target_period gentleness.ensemble_size "
    "gentleness.model_hidden gentleness.model_batch_size gentleness.model_buffer_size "
    "logging.eval_every_frames logging.log_every_updates logging.checkpoint_every_frames "
    "num_threads"
).split()
_NON_NEGATIVE = (
    "collector.init_random_frames gentleness.reward_delay logging.eval_episodes collector.sigma "
    "learner.policy_noise learner.utd_ratio gentleness.surprise_scale "
    "gentleness.dynamics_surprise_scale gentleness.icm_eta"
).split()


def validate(cfg: TrainConfig) -> None:
    """Raise one ``ValueError`` listing every problem, before anything starts."""
    problems = type_problems(cfg)
    if problems:  # the range checks below compare numbers
        raise ValueError("invalid training config:\n  - " + "\n  - ".join(problems))
    problems = consistency_problems(cfg)
    for name, f in iter_fields():
        choices = f.metadata.get("choices")
        if choices is not None:
            valid = list(choices() if callable(choices) else choices)
            if get(cfg, name) not in valid:
                problems.append(f"{name}={get(cfg, name)!r} is not one of {valid}")
    for name in _POSITIVE:
        if get(cfg, name) < 1:
            problems.append(f"{name}={get(cfg, name)} must be >= 1")
    for name in _NON_NEGATIVE:
        if not get(cfg, name) >= 0:
            problems.append(f"{name}={get(cfg, name)} must be >= 0")
    for name in ("learner.lr_actor", "learner.lr_critic", "gentleness.lr_model"):
        if not get(cfg, name) > 0:
            problems.append(f"{name}={get(cfg, name)} must be > 0")
    for name in ("network.actor_hidden", "network.critic_hidden"):
        if not get(cfg, name) or min(get(cfg, name)) < 1:
            problems.append(f"{name}={get(cfg, name)} must be a non-empty list of sizes >= 1")
    for name in ("gentleness.lam", "gentleness.lam_prime"):
        value = get(cfg, name)
        if len(value) != 2 or value[0] <= 0 or value[1] < 0:
            problems.append(f"{name}={value} must be [lambda_1 > 0, lambda_2 >= 0]")
    if not 0.0 < cfg.learner.gamma <= 1.0:
        problems.append(f"learner.gamma={cfg.learner.gamma} must be in (0, 1]")
    net = cfg.network
    if not net.v_min < net.v_max:
        problems.append(f"network.v_min={net.v_min} must be < network.v_max={net.v_max}")
    if net.bounded_support and not net.v_min < 0:
        problems.append(f"network.v_min={net.v_min} must be < 0 with bounded_support (v_max 0)")
    if net.dense_reward_bound is not None and not 0 < net.dense_reward_bound < float("inf"):
        problems.append(
            f"network.dense_reward_bound={net.dense_reward_bound} must be a finite number > 0 "
            "(or null: [v_min, v_max] for every head)"
        )
    col = cfg.collector
    if col.overlap and col.kind != "single":
        problems.append(f"collector.overlap=true needs collector.kind='single', got {col.kind!r}")
    if col.env_threads is not None and col.env_threads < 1:
        problems.append(f"collector.env_threads={col.env_threads} must be >= 1 (or null)")
    if col.num_envs is not None and col.num_envs < 1:
        problems.append(f"collector.num_envs={col.num_envs} must be >= 1 (or null: automatic)")
    if col.num_envs is not None and col.num_envs >= 1 and col.frames_per_batch % col.num_envs:
        problems.append(
            f"collector.frames_per_batch={col.frames_per_batch} must be a multiple of "
            f"collector.num_envs={col.num_envs}"
        )
    problems += _ray_problems(col)
    problems += _env_problems(cfg.env)
    replay = cfg.replay
    if not 0.0 <= replay.alpha <= 1.0 or not 0.0 <= replay.beta <= 1.0:
        problems.append(f"replay.alpha={replay.alpha} and beta={replay.beta} must be in [0, 1]")
    if problems:
        raise ValueError("invalid training config:\n  - " + "\n  - ".join(problems))


def _ray_problems(col: CollectorConfig) -> list[str]:
    problems = []
    for name in ("cpus_per_worker", "memory_per_worker_gb"):
        if not getattr(col, name) > 0:
            problems.append(f"collector.{name}={getattr(col, name)} must be > 0")
    if col.kind == "ray" and col.num_workers >= 1 and col.frames_per_batch % col.num_workers:
        problems.append(
            f"collector.frames_per_batch={col.frames_per_batch} must be a multiple of "
            f"collector.num_workers={col.num_workers} with collector.kind=ray"
        )
    if col.kind == "multi" and col.num_envs not in (None, 1):
        problems.append(
            f"collector.num_envs={col.num_envs} with collector.kind=multi: batched envs run in "
            "the single collector (num_envs=1 with multi; scale with num_workers)"
        )
    if col.kind == "ray" and col.num_envs not in (None, 1):
        problems.append(
            f"collector.num_envs={col.num_envs} with collector.kind=ray: one hand per Ray worker "
            "(num_envs=1); scale with num_workers"
        )
    if col.ray_address not in (None, "auto"):
        from gentlerl.distributed.cluster import parse_address

        try:
            parse_address(col.ray_address)
        except ValueError as err:
            problems.append(str(err))
    return problems


def _env_problems(env: EnvConfig) -> list[str]:
    """``env.name`` (a known external env), ``env.force_adapter`` (a known adapter, only with an
    external env) and ``env.observation_keys`` (only with an external env)."""
    from gentlerl.envs.external import FORCE_ADAPTERS, check_name

    if env.name is None:
        return [
            f"env.{name}={getattr(env, name)!r} applies to an external env only (set env.name)"
            for name in ("force_adapter", "observation_keys")
            if getattr(env, name) is not None
        ]
    problems = check_name(env.name)
    if env.force_adapter is not None and env.force_adapter not in FORCE_ADAPTERS:
        problems.append(
            f"env.force_adapter={env.force_adapter!r} is not one of {sorted(FORCE_ADAPTERS)}"
        )
    if env.observation_keys is not None and not env.observation_keys:
        problems.append("env.observation_keys=[] must name at least one entry (or null: all)")
    return problems
