"""Several seeds of one run in one process: each seed a run of its own, their updates one step.

A :class:`SeedGroup` is the :class:`~gentlerl.training.loop.Lockstep` of S seeds' configs,
equal but for ``seed`` and ``run_dir``, checked first (:func:`group_problems`): each seed keeps
its env stream, exploration noise, replay buffers, reward transforms, evaluations, logs and
checkpoints in its own run directory, and its checkpoint resumes as a run of its own
(``gentlerl train run_dir=... resume=true``). The updates are one: one
:class:`~gentlerl.agent.Learner` and one :class:`~gentlerl.rewards.model_step.ModelStep` per
model kind over every seed's networks. Each seed draws from its own random streams, so a
group's seeds log what they log alone (to float rounding). :func:`train_seeds` holds each
seed's run lock while the group trains.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import ExitStack

from gentlerl.config.layout import RunLayout
from gentlerl.files import folder_link_problem
from gentlerl.training.builders import EnvFactory, default_env_factory
from gentlerl.training.config import TrainConfig
from gentlerl.training.env_probe import probe_env
from gentlerl.training.loop import Lockstep, Trainer
from gentlerl.training.run_lock import RunLock

#: The settings in which a group's seeds may differ.
PER_SEED = ("seed", "run_dir")


def group_problems(cfgs: Sequence[TrainConfig]) -> list[str]:
    """Why ``cfgs`` cannot run as one seed group (empty: they can)."""
    if not cfgs:
        return ["a seed group needs at least one config, got 0"]
    first = {k: v for k, v in cfgs[0].to_dict().items() if k not in PER_SEED}
    problems = []
    for cfg in cfgs[1:]:
        other = {k: v for k, v in cfg.to_dict().items() if k not in PER_SEED}
        if other != first:
            keys = sorted(k for k in first if first[k] != other.get(k))
            problems.append(
                f"seed {cfg.seed}'s config differs from seed {cfgs[0].seed}'s in {keys}"
            )
    for name in PER_SEED:
        values = [str(getattr(cfg, name)) for cfg in cfgs]
        if len(set(values)) != len(values):
            problems.append(f"each seed needs its own {name}, got {values}")
    for cfg in cfgs:  # before any seed's trainer makes its folder
        if link := folder_link_problem(cfg.run_dir):
            problems.append(link)
        elif RunLayout(cfg.run_dir).checkpoint.exists():
            problems.append(
                f"run_dir={str(cfg.run_dir)!r} holds a checkpoint: a seed group does not resume; "
                "resume each seed's run on its own, or choose new run_dirs"
            )
    if cfgs[0].gentleness.multiplier != "none":
        problems.append(
            f"gentleness.multiplier={cfgs[0].gentleness.multiplier!r}: a seed group batches one "
            "penalty weight for every seed; run steered seeds one by one"
        )
    return problems


class SeedGroup(Lockstep):
    """The runs of ``cfgs`` (one variant, its seeds), trained together: :meth:`run`.

    Args:
        cfgs: one config per seed, equal but for ``seed`` and ``run_dir``.
        env_factory: as :func:`~gentlerl.training.loop.train` takes (each seed's env is seeded
            by its config's seed).
    """

    def __init__(self, cfgs: Sequence[TrainConfig], env_factory: EnvFactory | None = None) -> None:
        if problems := group_problems(cfgs):
            raise ValueError("; ".join(problems))
        super().__init__([Trainer(cfg, env_factory) for cfg in cfgs])


def available_memory() -> int | None:
    """The bytes this machine can still give (Linux's ``MemAvailable``); ``None`` elsewhere."""
    try:
        with open("/proc/meminfo") as f:
            fields = dict(line.split(":", 1) for line in f)
    except (OSError, ValueError):
        return None
    kb = fields.get("MemAvailable", "").split()
    return int(kb[0]) * 1024 if kb and kb[0].isdigit() else None


def group_memory_problem(
    cfgs: Sequence[TrainConfig], env_factory: EnvFactory | None = None
) -> str | None:
    """Why the replay buffers of ``cfgs`` would not fit this machine's free memory (``None``:
    they would). A lower bound: each seed keeps ``min(total_frames, replay.buffer_size)``
    transitions for the learner and ``min(total_frames, gentleness.model_buffer_size)`` for the
    models, each at least the size of one step of the env (probed once, both observations),
    before the keys the rewards and the n-step return add."""
    cfg = cfgs[0]
    env = probe_env(cfg, env_factory or default_env_factory(cfg))
    try:
        per_frame = env.rand_step(env.reset()).bytes()
    finally:
        env.close()
    frames = cfg.collector.total_frames
    stored = min(frames, cfg.replay.buffer_size) + min(frames, cfg.gentleness.model_buffer_size)
    need, free = len(cfgs) * stored * per_frame, available_memory()
    if free is None or need <= free:
        return None
    return (
        f"{len(cfgs)} seeds would keep at least {need / 1e9:.1f} GB of transitions ({stored:,} "
        f"a seed x {per_frame:,} bytes) and this machine has {free / 1e9:.1f} GB free: run fewer "
        "seeds a group, or lower collector.total_frames or replay.buffer_size"
    )


def train_seeds(
    cfgs: Sequence[TrainConfig], env_factory: EnvFactory | None = None
) -> list[dict[str, float]]:
    """Train the seeds of ``cfgs`` as one :class:`SeedGroup`, each seed's run directory locked
    (one writer each, as :func:`~gentlerl.training.loop.train` holds it); each seed's final
    evaluation. Refused before any folder is made: :func:`group_problems`, and a group whose
    buffers would not fit the free memory (:func:`group_memory_problem`)."""
    if problems := group_problems(cfgs):  # before any lock makes a folder
        raise ValueError("; ".join(problems))
    if memory := group_memory_problem(cfgs, env_factory):
        raise ValueError(memory)
    with ExitStack() as locks:
        for cfg in cfgs:
            locks.enter_context(RunLock(cfg.run_dir))
        return SeedGroup(cfgs, env_factory).run()
