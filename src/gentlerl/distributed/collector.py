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
from typing import Any

import torch
from torchrl.envs import EnvBase

from gentlerl.distributed.cluster import no_cluster, preflight, ray_init_config


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
) -> Any:
    """A synchronous ``RayCollector``: one remote collector per env factory (worker).

    Ray is started locally (``num_workers x cpus_per_worker`` CPUs) when ``address`` is None and
    no Ray runs in this process; ``"auto"``, ``host:port`` or ``ray://host:port`` joins a cluster.
    Each worker reserves ``cpus_per_worker`` CPUs and ``memory_per_worker_gb`` GiB. The collector's
    ``shutdown()`` kills the workers and stops a Ray it started.
    """
    num_workers = len(env_factories)
    if frames_per_batch % num_workers:
        raise ValueError(
            f"frames_per_batch={frames_per_batch} must be a multiple of num_workers={num_workers} "
            "(each Ray worker collects an equal share of a batch)"
        )
    if not cpus_per_worker > 0 or not memory_per_worker_gb > 0:
        raise ValueError(
            f"cpus_per_worker={cpus_per_worker} and memory_per_worker_gb={memory_per_worker_gb} "
            "must be > 0"
        )
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
