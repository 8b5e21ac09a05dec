"""The groups of a run's settings, each field declared once (:func:`~gentlerl.config.fields.setting`)
with its help, choices, range and whether a resume may change it
(:mod:`~gentlerl.config.rules`: the rules tying fields of a group together).

Defaults are the ``cpu`` scale; :data:`~gentlerl.config.presets.SCALES` holds the others.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gentlerl.config.fields import setting
from gentlerl.config.gentleness import GentlenessConfig
from gentlerl.config.limits import (
    MAX_BATCH,
    MAX_FRAMES,
    MAX_HANDS,
    MAX_THREADS,
    MAX_TRANSITIONS,
    MAX_WIDTH,
)

COLLECTORS = ("single", "multi", "ray")
#: collector.overlap: none, the next batch on a thread, or in a child process (a rule checks it:
#: the choices a field declares are names).
OVERLAPS = (False, True, "process")
WANDB_MODES = ("offline", "online", "disabled")
#: Where scalars go besides the CSV files that gentlerl plot reads (TorchRL ``get_logger`` types).
LOGGERS = ("csv", "wandb", "tensorboard")


@dataclass
class EnvConfig:
    kwargs: dict[str, Any] = setting({}, "keyword arguments of make_env, e.g. {time_limit: 100}")
    name: str | None = setting(
        None,
        "null: gentlerl's hand, task `task`; else a TorchRL env, 'dm_control:<domain>-<task>' "
        "'gym:<Gymnasium id>' or 'manipulation:<dm_control.manipulation name>' (e.g. "
        "dm_control:finger-spin, gym:Hopper-v5; kwargs then go to DMControlEnv / GymEnv)",
    )
    force_adapter: str | None = setting(
        None,
        "transforms bringing an external env's contact reading to force_key in N, "
        "[n_sites, n_channels] (null: dm_control_touch for a dm_control env with touch "
        "sensors, else contacts: MuJoCo's contact forces per env.force_groups; names: "
        "gentlerl.envs.external.FORCE_ADAPTERS)",
    )
    force_groups: dict[str, Any] = setting(
        {},
        "contacts adapter: the force sites, group -> body or geom names summed into it (on the "
        "command line +env.force_groups.feet=[left_foot,right_foot]; a body: its own geoms; "
        "subtree:NAME with its "
        "children; geom:NAME one geom); given with force_adapter null, contacts is used; {}: "
        "the env's default (gentlerl.envs.contacts.CONTACT_GROUPS)",
    )
    force_key: str | None = setting(
        None, "the force entry the gentleness rewards read (null: touch for the hand, else force)"
    )
    observation_keys: tuple[str, ...] | None = setting(
        None, "external env: entries concatenated into observation (null: all but pixels)"
    )
    reward_bounds: tuple[float, float] | None = setting(
        None,
        "per-step [low, high] of the task reward, from which network.derive_support sizes the "
        "task head (null: [0, 1] for dm_control, whose suite rewards lie in the unit interval)",
    )
    # The paper's lambda is in the newtons of the hand's fingertips; finger-spin's spinning
    # contacts reach 200-1,600 N, so its penalty is ~100x the hand's (measured).
    force_scale: float = setting(
        1.0,
        "external env: the adapted force is multiplied by this before the rewards read it "
        "(the unit lambda is in; 0.01 reads newtons as hundreds of newtons; reported impacts "
        "are then in that unit)",
        bounds="> 0",
    )

    @property
    def force(self) -> str:
        """The force entry the rewards read: ``force_key``, else the hand's ``touch`` or the
        external env's adapted ``force``."""
        if self.force_key is not None:
            return self.force_key
        return "touch" if self.name is None else "force"


#: Hands per collector env when ``collector.num_envs`` is null (the default) and the env factory
#: batches: 4 hands share each step's TorchRL and policy overhead (1.35x one hand's collector
#: frames/s on a quiet core, 1.98x at load 5-7; the default recipe 1.18x faster end to end with
#: the same evaluations).
AUTO_NUM_ENVS = 4


@dataclass
class CollectorConfig:
    kind: str = setting(
        "single",
        "one process, num_workers processes, or num_workers Ray actors",
        choices=COLLECTORS,
    )
    num_workers: int = setting(
        2, "env processes of the multi collector, Ray actors of the ray one", bounds="[1, 512]"
    )
    ray_address: str | None = setting(
        None,
        "ray: null starts a local Ray; auto, host:port or ray://host:port joins a cluster",
        resumable=True,
    )
    cpus_per_worker: float = setting(
        1.0, "ray: CPUs each remote collector reserves", bounds="(0, 256]", resumable=True
    )
    memory_per_worker_gb: float = setting(
        1.0, "ray: memory (GiB) each remote collector reserves", bounds="(0, 1024]",
        resumable=True,
    )  # fmt: skip
    weight_sync_every: int = setting(
        50, "ray: learner updates between weight pushes to the workers", bounds=">= 1",
        resumable=True,
    )  # fmt: skip
    num_envs: int | None = setting(
        None,
        "hands stepped together per collector env (BatchedHandEnv, kind=single); null: "
        f"{AUTO_NUM_ENVS} where the env factory batches (gentlerl's hand env), else 1",
        bounds=f"[1, {MAX_HANDS}]",
    )
    env_threads: int | None = setting(
        None,
        "physics threads of a batched env (null: 1 per hand, at most 1 per core)",
        bounds=f"[1, {MAX_THREADS}]",
        resumable=True,
    )
    overlap: bool | str = setting(
        False,
        "collect the next batch while the learner trains (one batch of policy lag): true on a "
        "thread, process in a child process (on another core)",
        resumable=True,
    )
    total_frames: int = setting(
        100_000, "env steps of the whole run", bounds=f"[1, {MAX_FRAMES}]", resumable=True
    )
    frames_per_batch: int = setting(
        200, "env steps per collector batch", bounds="[1, 100000]", resumable=True
    )
    init_random_frames: int = setting(
        10_000,
        "uniform random actions first (paper hand, 20 episodes each: 40 % succeed at touch, "
        "70 % break the fragile block)",
        bounds=f"[0, {MAX_FRAMES}]",
        resumable=True,
    )  # fmt: skip
    sigma: float = setting(
        0.3, "std of the Gaussian exploration noise on actions in [-1, 1]", bounds=">= 0",
        resumable=True,
    )  # fmt: skip


@dataclass
class ReplayConfig:
    buffer_size: int = setting(200_000, "n-step transitions kept", bounds=f"[1, {MAX_TRANSITIONS}]")
    batch_size: int = setting(
        128, "transitions per learner update", bounds=f"[1, {MAX_BATCH}]", resumable=True
    )
    n_steps: int = setting(5, "n of the n-step return", bounds="[1, 100]")
    prioritized: bool = setting(True, "prioritised replay on the critic loss, else uniform")
    alpha: float = setting(0.6, "priority exponent", bounds="[0, 1]", resumable=True)
    beta: float = setting(
        0.4, "initial importance-weight exponent, annealed to 1", bounds="[0, 1]", resumable=True
    )
    device: str = setting(
        "cpu",
        "where the learner's replay (transitions and priority trees) lives: cpu, or learner "
        "(on learner.device: a GPU learner then samples and re-prioritises without the host)",
        choices=("cpu", "learner"),
    )


@dataclass
class LearnerConfig:
    utd_ratio: float = setting(
        0.25, "learner (and model) updates per env step", bounds=">= 0", resumable=True
    )
    lr_actor: float = setting(1e-4, "Adam step size of the actor", bounds="> 0", resumable=True)
    lr_critic: float = setting(3e-4, "Adam step size of the critics", bounds="> 0", resumable=True)
    gamma: float = setting(0.99, "discount per env step", bounds="(0, 1]")
    target_update_period: int = setting(
        100, "updates between hard target-network copies", bounds=">= 1", resumable=True
    )
    policy_noise: float = setting(
        0.0, "TD3 target policy smoothing std (0: D4PG)", bounds=">= 0", resumable=True
    )
    normalize_values: bool = setting(
        False,
        "the actor sums each critic head's value divided by its batch's mean magnitude, so no "
        "component's units tip the trade-off (Method IV)",
    )
    episodic_intrinsic: bool = setting(
        False, "cut the curiosity heads' bootstrap at termination too", ablation=True
    )
    compile: bool = setting(
        False, "torch.compile the learner's update (the first updates compile it)"
    )
    cudagraphs: bool = setting(
        False, "replay the learner's update as a CUDA graph (needs learner.device=cuda)"
    )
    device: str = setting(
        "cpu",
        "where the D4PG networks, the reward models and their updates run: cpu, cuda or cuda:N "
        "(collection stays on the CPU, the replay unless replay.device=learner; the acting actor "
        "is a CPU copy)",
        resumable=True,
    )


@dataclass
class NetworkConfig:
    actor_hidden: tuple[int, ...] = setting(
        (256, 256), "hidden layer sizes of the actor", bounds=f"[1, {MAX_WIDTH}]"
    )
    critic_hidden: tuple[int, ...] = setting(
        (256, 256), "hidden layer sizes of each critic", bounds=f"[1, {MAX_WIDTH}]"
    )
    num_atoms: int = setting(
        101, "atoms of each critic head's categorical support", bounds="[1, 1001]"
    )
    derive_support: bool | None = setting(
        None,
        "size the task head's support from env.reward_bounds, learner.gamma and the episode "
        "length, with 10 % headroom (null: derived for an external env whose reward bounds are "
        "known, dm_control's or env.reward_bounds; else v_min/v_max)",
    )
    v_min: float = setting(-10.0, "bottom of every head's support")
    v_max: float = setting(10.0, "top of every head's support")
    bounded_support: bool = setting(
        True, "cap a head's v_max at its reward's bound (0 for penalties)", ablation=True
    )
    # Measured at the cpu scale (touch, r+rf+rsp, paper hand): realised discounted penalty returns
    # of -24 to -33 per episode start, outside [-10, 10]; r^sp ~1 per contact step. 1 x the
    # discounted horizon (86.6 for 200 steps at gamma 0.99) covers both.
    dense_reward_bound: float | None = setting(
        1.0,
        "per-step size of the dense rewards (penalty, curiosity): their heads span +-it x "
        "(1 - gamma^T) / (1 - gamma); null: every head gets [v_min, v_max]",
        bounds="> 0",
        ablation=True,
    )
    penalty_surprise_bound: float | None = setting(
        None,
        "per-step size of r^sp for its head's support (the same horizon factor); null: "
        "dense_reward_bound. A cap on the value of curiosity: 3 (uncapped on the hand) drops "
        "30k fragile from 1.00 to 0.30 (measured)",
        bounds="> 0",
        ablation=True,
    )


@dataclass
class LoggingConfig:
    eval_every_frames: int = setting(
        5_000, "env steps between evaluations", bounds=">= 1", resumable=True
    )
    eval_episodes: int = setting(
        10, "noise-free episodes per evaluation (stepped together as one batch of hands)",
        bounds=f"[0, {MAX_HANDS}]", resumable=True,
    )  # fmt: skip
    log_every_updates: int = setting(
        200, "updates averaged into one row of train/ scalars", bounds=">= 1", resumable=True
    )
    checkpoint_every_frames: int = setting(
        10_000, "env steps between checkpoints", bounds=">= 1", resumable=True
    )
    checkpoint_buffer: bool = setting(
        True, "keep the replay buffers in checkpoint.pt (false: much smaller; resume refills them)"
    )
    logger: str = setting(
        "csv", "csv only, or csv and wandb / tensorboard (TorchRL get_logger)", choices=LOGGERS
    )
    wandb_mode: str = setting(
        "offline",
        "wandb mode with logger=wandb (online prints its link)",
        choices=WANDB_MODES,
        resumable=True,
    )
    wandb_project: str = setting("gentlerl", "wandb project", resumable=True)
    progress: bool = setting(True, "show a progress bar", resumable=True)


GROUPS = {
    "env": EnvConfig,
    "collector": CollectorConfig,
    "replay": ReplayConfig,
    "learner": LearnerConfig,
    "network": NetworkConfig,
    "gentleness": GentlenessConfig,
    "logging": LoggingConfig,
}
