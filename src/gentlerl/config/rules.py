"""The rules tying fields of one group together, beyond each field's declared range: one line per
problem, naming the fields."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from gentlerl.config.fields import declared_problems, type_problems
from gentlerl.config.groups import (
    OVERLAPS,
    CollectorConfig,
    EnvConfig,
    GentlenessConfig,
    LearnerConfig,
    LoggingConfig,
    NetworkConfig,
    ReplayConfig,
)

#: A config group: an instance of one of :data:`~gentlerl.config.groups.GROUPS`' classes.
ConfigGroup = (
    EnvConfig
    | CollectorConfig
    | ReplayConfig
    | LearnerConfig
    | NetworkConfig
    | GentlenessConfig
    | LoggingConfig
)


def collector_problems(col: CollectorConfig) -> list[str]:
    """Overlap is false, true (a thread) or process, and needs the single collector; a batch
    splits evenly over ``num_envs`` hands, which only the single collector batches (the multi and
    Ray collectors step one hand per worker)."""
    problems = []
    if col.overlap not in OVERLAPS:
        problems.append(f"collector.overlap={col.overlap!r} must be true, false or process")
    elif col.overlap and col.kind != "single":
        problems.append(
            f"collector.overlap={str(col.overlap).lower()} needs collector.kind='single', "
            f"got {col.kind!r}"
        )
    if col.num_envs is not None and col.num_envs >= 1 and col.frames_per_batch % col.num_envs:
        problems.append(
            f"collector.frames_per_batch={col.frames_per_batch} must be a multiple of "
            f"collector.num_envs={col.num_envs}"
        )
    if col.kind != "single" and col.num_envs not in (None, 1):
        problems.append(
            f"collector.num_envs={col.num_envs} with collector.kind={col.kind}: batched envs run "
            f"in the single collector (num_envs=1 with {col.kind}; scale with num_workers)"
        )
    return problems


def replay_problems(replay: ReplayConfig) -> list[str]:
    """The buffer holds at least one batch."""
    if replay.buffer_size < replay.batch_size:
        return [
            f"replay.buffer_size={replay.buffer_size} must be >= replay.batch_size="
            f"{replay.batch_size} (no update could ever sample a batch)"
        ]
    return []


#: Hidden layers of the actor or a critic (each layer's size is bounded by its field).
MAX_LAYERS = 8


def network_problems(net: NetworkConfig) -> list[str]:
    """One to :data:`MAX_LAYERS` hidden layers, and a support with its bottom below its top
    (below 0 when penalties top at 0)."""
    problems = [
        f"network.{name}={list(sizes)} must list 1 to {MAX_LAYERS} layer sizes"
        for name, sizes in (
            ("actor_hidden", net.actor_hidden),
            ("critic_hidden", net.critic_hidden),
        )
        if not 1 <= len(sizes) <= MAX_LAYERS
    ]
    if not net.v_min < net.v_max:
        problems.append(f"network.v_min={net.v_min} must be < network.v_max={net.v_max}")
    if net.bounded_support and not net.v_min < 0:
        problems.append(f"network.v_min={net.v_min} must be < 0 with bounded_support (v_max 0)")
    return problems


def gentleness_problems(gentleness: GentlenessConfig) -> list[str]:
    """Both gates ``[lambda_1, lambda_2]`` of eq. 3 and 8: a positive scale, a non-negative
    offset; a multiplier needs the tolerance it steers toward, and three PID gains."""
    problems = [
        f"gentleness.{name}={value} must be [lambda_1 > 0, lambda_2 >= 0]"
        for name, value in (("lam", gentleness.lam), ("lam_prime", gentleness.lam_prime))
        if len(value) != 2 or value[0] <= 0 or value[1] < 0
    ]
    if gentleness.multiplier != "none" and gentleness.tolerance is None:
        problems.append(
            f"gentleness.multiplier={gentleness.multiplier} steers toward the tolerance: set "
            "gentleness.tolerance (the impact one step may deal, N)"
        )
    default = type(gentleness)()
    unused = {  # each set away from its default under another multiplier, where it is unused
        "pid": (
            "multiplier_period",
            "multiplier_integral_max",
            "multiplier_base",
            "multiplier_episodes",
        ),
        "lagrangian": (
            "cost_limit",
            "cost_gains",
            "cost_warmup_frames",
            "cost_period",
            "cost_multiplier_max",
        ),
    }
    problems += [
        f"gentleness.{name}={getattr(gentleness, name)} applies to gentleness.multiplier={kind} "
        "only"
        for kind, names in unused.items()
        if gentleness.multiplier != kind
        for name in names
        if getattr(gentleness, name) != getattr(default, name)
    ]
    if (
        gentleness.multiplier == "pid"
        and gentleness.multiplier_episodes
        and gentleness.multiplier_period is None
    ):
        problems.append(
            f"gentleness.multiplier_episodes={gentleness.multiplier_episodes} runs at each PID "
            "step: set gentleness.multiplier_period (env steps between them)"
        )
    problems += [
        f"gentleness.{name}={getattr(gentleness, name)} must be [K_P, K_I, K_D]"
        for name in ("multiplier_gains", "cost_gains")
        if len(getattr(gentleness, name)) != 3
    ]
    return problems


def learner_problems(learner: LearnerConfig) -> list[str]:
    """``device`` names a device torch has here (cpu, cuda, cuda:N), and ``cudagraphs`` a CUDA
    one."""
    device = learner.device
    if not re.fullmatch(r"cpu|cuda(:\d+)?", device):
        return [f"learner.device={device!r} must be cpu, cuda or cuda:N"]
    if device.startswith("cuda"):
        import torch

        index = int(device.partition(":")[2] or 0)
        if not torch.cuda.is_available() or index >= torch.cuda.device_count():
            found = torch.cuda.device_count() if torch.cuda.is_available() else 0
            return [f"learner.device={device!r}: torch sees {found} CUDA device(s) here"]
    elif learner.cudagraphs:
        return [f"learner.cudagraphs=true needs learner.device=cuda, got {device!r}"]
    return []


#: The rules of each group beyond its fields' declared ranges, by group name.
GROUP_RULES: dict[str, Callable[[Any], list[str]]] = {
    "collector": collector_problems,
    "replay": replay_problems,
    "learner": learner_problems,
    "network": network_problems,
    "gentleness": gentleness_problems,
}


def check_group(config: ConfigGroup, name: str) -> None:
    """The checks ``gentlerl train`` makes of the group ``name`` (types, declared ranges, its
    rule), for a group built in Python (``IntrinsicRewards(settings=GentlenessConfig(...))``):
    one ``ValueError`` listing every problem, fields named as the CLI names them."""
    prefix = f"{name}."
    problems = type_problems(config, prefix)
    if not problems:  # the range checks compare numbers
        problems = declared_problems(config, prefix) + GROUP_RULES.get(name, lambda _: [])(config)
    if problems:
        raise ValueError(f"invalid {type(config).__name__}: " + "; ".join(problems))
