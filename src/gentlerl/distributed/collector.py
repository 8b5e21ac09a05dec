"""``collector.kind=ray``: TorchRL's ``RayCollector`` with ``num_workers`` remote env collectors.

Each Ray actor runs one TorchRL ``Collector`` over its own env with a copy of the exploration
policy; the learner pushes its weights with ``update_policy_weights_()`` (TorchRL's
``RayWeightSyncScheme``). Batches are synchronous: every worker returns ``frames_per_batch /
num_workers`` steps and they are stacked into ``[num_workers, T]``, each row one worker's
time-contiguous steps (what the n-step replay transform needs), as the ``multi`` collector does.
The reward-model transforms run in the learner on the stacked batch.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from gentlerl.config.fields import declared_problems, type_problems
from gentlerl.config.groups import CollectorConfig
from gentlerl.distributed.cluster import no_cluster, parse_address, preflight, ray_init_config

if TYPE_CHECKING:
    import torch
    from torchrl.collectors import BaseCollector
    from torchrl.envs import EnvBase


def ray_problems(col: CollectorConfig) -> list[str]:
    """The Ray collector's rules beyond each field's declared range (one line per problem):
    with ``kind=ray`` a batch splits evenly over the workers; a cluster address is for
    ``kind=ray`` only (ignored otherwise), and must parse. (One hand per worker is :func:`gentlerl.config.rules.collector_problems`'
    rule, shared with the multi collector.)"""
    problems = []
    if col.kind == "ray" and col.num_workers >= 1 and col.frames_per_batch % col.num_workers:
        problems.append(
            f"collector.frames_per_batch={col.frames_per_batch} must be a multiple of "
            f"collector.num_workers={col.num_workers} with collector.kind=ray (each Ray worker "
            "collects an equal share of a batch)"
        )
    if col.ray_address is not None and col.kind != "ray":
        problems.append(
            f"collector.ray_address={col.ray_address!r} applies to collector.kind=ray only "
            f"(got collector.kind={col.kind!r}); set it to null or use the Ray collector"
        )
    elif col.ray_address not in (None, "auto"):
        try:
            parse_address(col.ray_address)
        except ValueError as err:
            problems.append(f"collector.ray_address={err}")
    return problems


def make_ray_collector(
    env_factories: Sequence[Callable[[], EnvBase]],
    policy: torch.nn.Module,
    *,
    frames_per_batch: int,
    total_frames: int,
    init_random_frames: int,
    address: str | None = None,
    cpus_per_worker: float = 1.0,
    memory_per_worker_gb: float = 1.0,
) -> BaseCollector:
    """A synchronous ``RayCollector``: one remote collector per env factory (worker).

    Ray is started locally (``num_workers x cpus_per_worker`` CPUs) when ``address`` is None and
    no Ray runs in this process; ``"auto"``, ``host:port`` or ``ray://host:port`` joins a cluster.
    Each worker reserves ``cpus_per_worker`` CPUs and ``memory_per_worker_gb`` GiB. The collector's
    ``shutdown()`` kills the workers and stops a Ray it started. ``total_frames`` and
    ``init_random_frames`` count what is left of the run; the other settings are checked first,
    as ``collector`` settings (their declarations and :func:`ray_problems`): a ``ValueError``.
    """
    num_workers = len(env_factories)
    settings = CollectorConfig(
        kind="ray",
        num_workers=num_workers,
        ray_address=address,
        cpus_per_worker=cpus_per_worker,
        memory_per_worker_gb=memory_per_worker_gb,
        frames_per_batch=frames_per_batch,
    )
    prefix = "collector."
    problems = type_problems(settings, prefix) or (
        declared_problems(settings, prefix) + ray_problems(settings)
    )
    if problems:
        raise ValueError("invalid Ray collector settings:\n  - " + "\n  - ".join(problems))
    preflight(address)
    from torchrl.collectors import Collector

    try:
        return Collector(
            list(env_factories),
            policy,
            backend="ray",
            num_collectors=num_workers,
            sync=True,
            frames_per_batch=frames_per_batch,
            total_frames=total_frames,
            init_random_frames=init_random_frames,
            ray_init_config=ray_init_config(address, num_workers * cpus_per_worker),
            remote_configs={
                "num_cpus": cpus_per_worker,
                "memory": int(memory_per_worker_gb * 2**30),
            },
            # The policy is stateless: the env needs no InitTracker / primer.
            collector_kwargs={"auto_register_policy_transforms": False},
        )
    except ConnectionError as err:
        raise no_cluster(address, err) from err
