"""The schema of a run's config: groups of fields, each with its one-line help and choices.

A field's ``help`` (and its ``choices``) is what ``gentlerl-train --help`` prints; defaults are
the ``cpu`` scale. :mod:`gentlerl.training.config` builds and validates configs from it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from gentlerl.training.presets import SCALES

COLLECTORS = ("single", "multi", "ray")
WANDB_MODES = ("offline", "online", "disabled")
#: Where scalars go besides the CSV files that gentlerl plot reads (TorchRL ``get_logger`` types).
LOGGERS = ("csv", "wandb", "tensorboard")


def _task_names() -> list[str]:
    from gentlerl.envs import TASKS

    return list(TASKS)


def _variant_names() -> list[str]:
    from gentlerl.agent.variants import VARIANTS

    return list(VARIANTS)


def _scale_names() -> list[str]:
    return list(SCALES)


def _f(default: Any, help: str, choices: Callable[[], list[str]] | tuple | None = None) -> Any:
    """A field with its one-line help (and its valid choices) as metadata."""
    meta = {"help": help, "choices": choices}
    if isinstance(default, dict | list):
        return field(default_factory=lambda: type(default)(default), metadata=meta)
    return field(default=default, metadata=meta)


@dataclass
class EnvConfig:
    kwargs: dict[str, Any] = _f({}, "keyword arguments of make_env, e.g. {time_limit: 100}")
    name: str | None = _f(
        None,
        "null: gentlerl's hand, task `task`; else a TorchRL env, 'dm_control:<domain>-<task>' "
        "(e.g. dm_control:finger-spin; kwargs then go to DMControlEnv)",
    )
    force_adapter: str | None = _f(
        None,
        "transforms bringing an external env's contact reading to force_key in N, "
        "[n_sites, n_channels] (null: the source's, dm_control_touch for dm_control; "
        "names: gentlerl.envs.external.FORCE_ADAPTERS)",
    )
    force_key: str | None = _f(
        None, "the force entry the gentleness rewards read (null: touch for the hand, else force)"
    )
    observation_keys: tuple[str, ...] | None = _f(
        None, "external env: entries concatenated into observation (null: all but pixels)"
    )

    @property
    def force(self) -> str:
        """The force entry the rewards read: ``force_key``, else the hand's ``touch`` or the
        external env's adapted ``force``."""
        if self.force_key is not None:
            return self.force_key
        return "touch" if self.name is None else "force"


#: Hands per collector env when ``collector.num_envs`` is null and the env factory batches: 4 hands
#: on the 2 physics threads of a 2-core machine (benchmarks/RESULTS.md, "train_speed"). Not the
#: default: the default recipe with 4 hands did not learn touch in 30k frames on 2 seeds, where one
#: hand learns it by 20k (README, "Measured numbers").
AUTO_NUM_ENVS = 4


@dataclass
class CollectorConfig:
    kind: str = _f(
        "single", "one process, num_workers processes, or num_workers Ray actors", COLLECTORS
    )
    num_workers: int = _f(2, "env processes of the multi collector, Ray actors of the ray one")
    ray_address: str | None = _f(
        None, "ray: null starts a local Ray; auto, host:port or ray://host:port joins a cluster"
    )
    cpus_per_worker: float = _f(1.0, "ray: CPUs each remote collector reserves")
    memory_per_worker_gb: float = _f(1.0, "ray: memory (GiB) each remote collector reserves")
    weight_sync_every: int = _f(50, "ray: learner updates between weight pushes to the workers")
    num_envs: int | None = _f(
        1,
        "hands stepped together per collector env (BatchedHandEnv, kind=single); null: "
        f"{AUTO_NUM_ENVS} where the env factory batches (gentlerl's hand env), else 1",
    )
    env_threads: int | None = _f(
        None, "physics threads of a batched env (null: 1 per hand, at most 1 per core)"
    )
    overlap: bool = _f(False, "collect the next batch on a thread while the learner trains")
    total_frames: int = _f(100_000, "env steps of the whole run")
    frames_per_batch: int = _f(200, "env steps per collector batch")
    init_random_frames: int = _f(10_000, "uniform random actions first (~1 % of them succeed)")
    sigma: float = _f(0.3, "std of the Gaussian exploration noise on actions in [-1, 1]")


@dataclass
class ReplayConfig:
    buffer_size: int = _f(200_000, "n-step transitions kept")
    batch_size: int = _f(128, "transitions per learner update")
    n_steps: int = _f(5, "n of the n-step return")
    prioritized: bool = _f(True, "prioritised replay on the critic loss, else uniform")
    alpha: float = _f(0.6, "priority exponent")
    beta: float = _f(0.4, "initial importance-weight exponent, annealed to 1")


@dataclass
class LearnerConfig:
    utd_ratio: float = _f(0.25, "learner (and model) updates per env step")
    lr_actor: float = _f(1e-4, "Adam step size of the actor")
    lr_critic: float = _f(3e-4, "Adam step size of the critics")
    gamma: float = _f(0.99, "discount per env step")
    target_update_period: int = _f(100, "updates between hard target-network copies")
    policy_noise: float = _f(0.0, "TD3 target policy smoothing std (0: D4PG)")
    episodic_intrinsic: bool = _f(False, "cut the curiosity heads' bootstrap at termination too")
    compile: bool = _f(False, "torch.compile the learner's update (the first updates compile it)")
    cudagraphs: bool = _f(False, "replay the learner's update as a CUDA graph (CUDA learners only)")


@dataclass
class NetworkConfig:
    actor_hidden: tuple[int, ...] = _f((256, 256), "hidden layer sizes of the actor")
    critic_hidden: tuple[int, ...] = _f((256, 256), "hidden layer sizes of each critic")
    num_atoms: int = _f(101, "atoms of each critic head's categorical support")
    v_min: float = _f(-10.0, "bottom of every head's support")
    v_max: float = _f(10.0, "top of every head's support")
    bounded_support: bool = _f(True, "cap a head's v_max at its reward's bound (0 for penalties)")
    # Measured at the cpu scale (touch, r+rf+rsp, paper hand): realised discounted penalty returns
    # of -24 to -33 per episode start, outside [-10, 10]; r^sp ~1 per contact step. 1 x the
    # discounted horizon (86.6 for 200 steps at gamma 0.99) covers both.
    dense_reward_bound: float | None = _f(
        1.0,
        "per-step size of the dense rewards (penalty, curiosity): their heads span +-it x "
        "(1 - gamma^T) / (1 - gamma); null: every head gets [v_min, v_max]",
    )


@dataclass
class GentlenessConfig:
    lam: tuple[float, float] = _f((2.0, 2.0), "impact acceptability [lambda_1, lambda_2] (eq. 3)")
    lam_prime: tuple[float, float] = _f((2.0, 2.0), "penalty-surprise gate [l'_1, l'_2] (eq. 8)")
    reward_delay: int = _f(2_000, "model updates before the curiosity rewards switch on")
    dynamics_target_period: int = _f(500, "model updates between dynamics target copies")
    penalty_target_period: int = _f(100, "model updates between penalty target copies")
    ensemble_size: int = _f(5, "members of each model ensemble")
    model_hidden: int = _f(128, "units of each of the models' 3 hidden layers")
    model_batch_size: int = _f(64, "transitions per ensemble member and model update")
    model_buffer_size: int = _f(100_000, "1-step transitions kept for the models")
    lr_model: float = _f(1e-3, "Adam step size of the models")
    surprise_scale: float = _f(
        1.0, "multiplies r^s and the NLL inside r^sp (not its refund of r^f)"
    )
    # r^s (eq. 6) is an NLL summed over 63 state dimensions: measured at CPU scale (touch, r+rf+rs)
    # 7-54 per step after the switch, so its non-episodic critic (value ~ r / (1 - gamma)) sat at
    # the support's +10 top. 1/500 maps the largest measured r^s to ~10 (docs/REPRODUCTION.md).
    dynamics_surprise_scale: float = _f(0.002, "extra factor on the dynamics surprise r^s")
    # Measured (docs/REPRODUCTION.md, fifth amendment): with supports per head and r^sp
    # recomputed at sampling, the fragile probe ended at 1.00 without a floor and 0.85 with 0;
    # the NLL of contact steps stayed near +1 at 30k frames either way.
    surprise_nll_floor: float | None = _f(None, "floor of the penalty-surprise NLL (null: eq. 8)")
    recompute_surprise: bool = _f(
        True, "recompute r^sp of each sampled n-step transition with the current target model"
    )
    icm_eta: float = _f(1.0, "scale eta of the ICM reward")


@dataclass
class LoggingConfig:
    eval_every_frames: int = _f(5_000, "env steps between evaluations")
    eval_episodes: int = _f(10, "noise-free episodes per evaluation")
    log_every_updates: int = _f(200, "updates averaged into one row of train/ scalars")
    checkpoint_every_frames: int = _f(10_000, "env steps between checkpoints")
    checkpoint_buffer: bool = _f(
        True, "keep the replay buffers in checkpoint.pt (false: much smaller; resume refills them)"
    )
    logger: str = _f(
        "csv", "csv only, or csv and wandb / tensorboard (TorchRL get_logger)", LOGGERS
    )
    wandb_mode: str = _f(
        "offline", "wandb mode with logger=wandb (online prints its link)", WANDB_MODES
    )
    wandb_project: str = _f("gentlerl", "wandb project")
    progress: bool = _f(True, "show a progress bar")


GROUPS = {
    "env": EnvConfig,
    "collector": CollectorConfig,
    "replay": ReplayConfig,
    "learner": LearnerConfig,
    "network": NetworkConfig,
    "gentleness": GentlenessConfig,
    "logging": LoggingConfig,
}


@dataclass
class TrainConfig:
    """A training run: what it is (task, variant, seed, scale), where it goes, and its groups."""

    task: str = _f("touch", "the env task", _task_names)
    variant: str = _f("r+rf+rsp", "reward components, one critic head each", _variant_names)
    seed: int = _f(0, "seeds torch, numpy, python, the envs and the models")
    scale: str = _f("cpu", "preset applied under the overrides", _scale_names)
    run_dir: str = _f("runs/default", "where the run writes everything")
    resume: bool | str = _f(False, "continue run_dir's run: true, false (start), auto (either)")
    num_threads: int = _f(1, "torch threads (the env and workers need the other cores)")
    env: EnvConfig = field(default_factory=EnvConfig)
    collector: CollectorConfig = field(default_factory=CollectorConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    learner: LearnerConfig = field(default_factory=LearnerConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    gentleness: GentlenessConfig = field(default_factory=GentlenessConfig)
    logging: LoggingConfig = field(default_factory=LoggingConfig)

    @property
    def reward_keys(self) -> list[str]:
        from gentlerl.agent.variants import reward_keys

        return reward_keys(self.variant)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def iter_fields() -> Iterator[tuple[str, dataclasses.Field]]:
    """``("group.name" or "name", field)`` for every leaf field of :class:`TrainConfig`."""
    for f in dataclasses.fields(TrainConfig):
        if f.name in GROUPS:
            for sub in dataclasses.fields(GROUPS[f.name]):
                yield f"{f.name}.{sub.name}", sub
        else:
            yield f.name, f


def get(cfg: TrainConfig, name: str) -> Any:
    """The value of ``"group.field"`` (or a top-level ``"field"``)."""
    value: Any = cfg
    for part in name.split("."):
        value = getattr(value, part)
    return value
