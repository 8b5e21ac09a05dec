"""A training run's config: :class:`TrainConfig` (what the run is, where it goes, and the groups
of :mod:`gentlerl.config`), built from a scale preset and overrides, and validated up front.

Each field is declared once (:func:`~gentlerl.config.fields.setting`): :func:`validate` runs the
checks :data:`CHECKS` lists, in one place: the declarations' types, then their choices and ranges
and the rules that tie fields together (each group's, the Ray address, the env's keywords).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from gentlerl import keys
from gentlerl.config import fields
from gentlerl.config.fields import setting
from gentlerl.config.groups import (
    GROUPS,
    MAX_THREADS,
    CollectorConfig,
    EnvConfig,
    GentlenessConfig,
    LearnerConfig,
    LoggingConfig,
    NetworkConfig,
    ReplayConfig,
)
from gentlerl.config.layout import run_dir_problem
from gentlerl.config.limits import MAX_SEED
from gentlerl.config.presets import SCALES
from gentlerl.config.rules import GROUP_RULES
from gentlerl.distributed.collector import ray_problems

__all__ = [
    "TrainConfig",
    "iter_fields",
    "make_config",
    "preset_config",
    "validate",
]


def _task_names() -> list[str]:
    from gentlerl.envs.task_names import TASK_NAMES

    return list(TASK_NAMES)


def _variant_names() -> list[str]:
    from gentlerl.rewards.variants import VARIANTS

    return list(VARIANTS)


def _scale_names() -> list[str]:
    return list(SCALES)


@dataclass
class TrainConfig:
    """A training run: what it is (task, variant, seed, scale), where it goes, and its groups."""

    task: str = setting(
        "touch",
        "the env task (touch: success is a fingerpad press > 5 N, which random actions often "
        "reach, so the measure is how gently; fragile: also broken by an impact > 3 N)",
        choices=_task_names,
    )
    variant: str = setting(
        "r+rf+rsp", "reward components, one critic head each", choices=_variant_names
    )
    seed: int = setting(
        0, "seeds torch, numpy, python, the envs and the models", bounds=f"[0, {MAX_SEED}]"
    )
    scale: str = setting(
        "cpu", "preset applied under the overrides", choices=_scale_names, resumable=True
    )
    run_dir: str = setting("runs/default", "where the run writes everything", resumable=True)
    resume: bool | str = setting(
        False, "continue run_dir's run: true, false (start), auto (either)", resumable=True
    )
    num_threads: int = setting(
        1, "torch threads (the env and workers need the other cores)",
        bounds=f"[1, {MAX_THREADS}]",
        resumable=True,
    )  # fmt: skip
    env: EnvConfig = field(default_factory=EnvConfig)
    collector: CollectorConfig = field(default_factory=CollectorConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    learner: LearnerConfig = field(default_factory=LearnerConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    gentleness: GentlenessConfig = field(default_factory=GentlenessConfig)
    logging: LoggingConfig = field(default_factory=LoggingConfig)

    @property
    def reward_keys(self) -> list[str]:
        from gentlerl.rewards.variants import reward_keys

        return reward_keys(self.variant)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def iter_fields() -> Iterator[tuple[str, dataclasses.Field]]:
    """``("group.name" or "name", field)`` for every leaf field of :class:`TrainConfig`."""
    return fields.iter_fields(TrainConfig)


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
    if not isinstance(scale, str) or scale not in SCALES:  # a list is no key (unhashable)
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


def _resume_problems(cfg: TrainConfig) -> list[str]:
    """true: continue (needs the checkpoint); false: start (refuses an existing run); auto: either."""
    if isinstance(cfg.resume, bool) or cfg.resume == "auto":
        return []
    return [f"resume={cfg.resume!r} must be true, false or 'auto'"]


def _run_problems(cfg: TrainConfig) -> list[str]:
    """A resumed collector's seed numpy takes (the seed plus the frames so far), a run directory
    that can be one (:func:`run_dir_problem`), and a penalty head for ``gentleness.multiplier``
    to weigh."""
    problems = []
    if cfg.seed + cfg.collector.total_frames >= 2**32:
        problems.append(
            f"seed={cfg.seed} + collector.total_frames={cfg.collector.total_frames} must be "
            "< 2**32 (a resumed run seeds its collector with seed + the frames so far, numpy "
            "takes seeds below 2**32)"
        )
    if cfg.gentleness.multiplier == "pid" and keys.PENALTY not in cfg.reward_keys:
        problems.append(
            f"gentleness.multiplier={cfg.gentleness.multiplier} weighs the penalty head, which "
            f"variant={cfg.variant} lacks (use a variant with rf)"
        )
    if cfg.gentleness.multiplier == "lagrangian" and not {
        keys.PENALTY,
        keys.EXCESS_PENALTY,
    } & set(cfg.reward_keys):
        problems.append(
            f"gentleness.multiplier=lagrangian weighs a cost head, which variant={cfg.variant} "
            "lacks (use a variant with rc or rf)"
        )
    problem = run_dir_problem(cfg.run_dir)
    return problems + _support_problems(cfg) + ([problem] if problem else [])


def _support_problems(cfg: TrainConfig) -> list[str]:
    """A derived task support needs the reward's bounds and leaves ``v_min``/``v_max`` unset."""
    from gentlerl.rewards.variants import derives_support, task_reward_bounds

    bounds = cfg.env.reward_bounds
    if bounds is not None and not (len(bounds) == 2 and bounds[0] <= bounds[1]):
        return [f"env.reward_bounds={list(bounds)} must be [low, high] with low <= high"]
    if not derives_support(cfg.env, cfg.network):
        return []
    default = type(cfg.network)()
    problems = [
        f"network.{name}={getattr(cfg.network, name)} sizes a hand-set support; this run derives "
        "the task head's (network.derive_support=false to set it by hand)"
        for name in ("v_min", "v_max")
        if getattr(cfg.network, name) != getattr(default, name)
    ]
    try:
        task_reward_bounds(cfg.env)
    except ValueError as err:
        problems.append(str(err))
    return problems


def _group_problems(cfg: TrainConfig) -> list[str]:
    """Each group's rules beyond its fields' declared ranges (:data:`GROUP_RULES`)."""
    return [p for name, rule in GROUP_RULES.items() for p in rule(getattr(cfg, name))]


def _ray_problems(cfg: TrainConfig) -> list[str]:
    """The Ray collector's rules (:func:`~gentlerl.distributed.collector.ray_problems`)."""
    return ray_problems(cfg.collector)


def _env_problems(cfg: TrainConfig) -> list[str]:
    """``env.kwargs`` the hand's task accepts (listing the valid ones), ``env.name`` (a known
    external env, its keywords that would fail only later), ``env.force_adapter``,
    ``env.force_groups`` (names the env's model has),
    ``env.observation_keys`` (each once) and ``env.force_scale`` (only with an external env; the
    adapter a known one). The env modules (MuJoCo, TorchRL) are imported only to check what
    needs them: task keywords, an external env."""
    env = cfg.env
    if env.name is None:
        problems = [
            f"env.{name}={getattr(env, name)!r} applies to an external env only (set env.name)"
            for name in ("force_adapter", "force_groups", "observation_keys")
            if getattr(env, name) not in (None, {})
        ]
        if env.force_scale != 1.0:
            problems.append(
                f"env.force_scale={env.force_scale!r} applies to an external env only "
                "(set env.name; the hand's touch is in newtons)"
            )
        if env.kwargs and cfg.task in _task_names():
            from gentlerl.envs.factory import env_kwarg_names
            from gentlerl.envs.task_names import RENAMED_KWARGS

            valid = env_kwarg_names(cfg.task)
            unknown = sorted(set(env.kwargs) - set(valid))
            problems += [
                f"env.kwargs.{k} is now env.kwargs.{RENAMED_KWARGS[k]} (the hand's physics regime)"
                for k in unknown
                if k in RENAMED_KWARGS
            ]
            unknown = [k for k in unknown if k not in RENAMED_KWARGS]
            if unknown:
                problems.append(
                    f"env.kwargs {unknown} are not keywords of task {cfg.task!r}; valid: {valid}"
                )
        return problems
    from gentlerl.envs.external import (
        FORCE_ADAPTERS,
        check_name,
        group_problems,
        kwargs_problems,
    )

    problems = check_name(env.name) + kwargs_problems(env.kwargs)  # they go to the external env
    if env.force_adapter is not None and env.force_adapter not in FORCE_ADAPTERS:
        problems.append(
            f"env.force_adapter={env.force_adapter!r} is not one of {sorted(FORCE_ADAPTERS)}"
        )
    elif not problems:  # the env exists: the groups' names are checked against its model
        problems += group_problems(env.name, env.force_adapter, env.force_groups or None)
    keys = env.observation_keys
    if keys is not None and not keys:
        problems.append("env.observation_keys=[] must name at least one entry (or null: all)")
    elif keys is not None and len(set(keys)) < len(keys):
        twice = sorted({k for k in keys if keys.count(k) > 1})
        problems.append(f"env.observation_keys={list(keys)} names {twice} more than once")
    return problems


#: Every check of a run's config, in two passes: the types (and ``resume``'s three values) first,
#: since the second pass compares numbers; then each field's declared choices and range and the
#: rules that tie fields together. Adding a check is adding it here.
CHECKS: tuple[tuple[Callable[[TrainConfig], list[str]], ...], ...] = (
    (fields.type_problems, _resume_problems),
    (fields.declared_problems, _run_problems, _group_problems, _ray_problems, _env_problems),
)


def validate(cfg: TrainConfig) -> None:
    """Raise one ``ValueError`` listing every problem of a pass of :data:`CHECKS`, before
    anything starts."""
    for checks in CHECKS:
        problems = [problem for check in checks for problem in check(cfg)]
        if problems:
            raise ValueError("invalid training config:\n  - " + "\n  - ".join(problems))
