"""Collection overlapped with learning: the next batch is collected on a thread
(:class:`PrefetchCollector`) or in a child process
(:class:`~gentlerl.training.process_collector.ProcessCollector`).

:class:`PrefetchCollector` iterates a TorchRL ``Collector`` one batch ahead on a background
thread, so that the hands' physics (``mujoco.mj_step`` releases the GIL) and the policy run
while the caller's learner updates run (torch kernels release the GIL too): both cores busy in
one process. The collector's policy is a *copy* of the actor, refreshed from the learner's actor
only between batches, while the thread is idle: batch ``k + 1`` is collected with the weights the
learner had after training on batch ``k - 1`` (one batch of policy lag, whatever the timing), and
the exploration noise draws from its own seeded generator, so the thread and the learner never
share a random stream; the random frames (TorchRL's ``init_random_frames``, drawn from the
global generator) are collected one batch at a time, not beside the caller. Same seed, same run. Batches come out in order, time-contiguous per env
row, as the n-step replay needs.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.collectors import Collector
from torchrl.modules import AdditiveGaussianModule


class SeededGaussianNoise(AdditiveGaussianModule):
    """TorchRL's additive Gaussian noise from its own ``torch.Generator``; always on.

    TorchRL's module draws from the global generator and reads the process-wide exploration
    type, which an evaluation on another thread may set: a collection thread must not depend on
    either.
    """

    def __init__(self, *args, seed: int = 0, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.generator = torch.Generator().manual_seed(seed)

    def _add_noise(self, action: torch.Tensor) -> torch.Tensor:
        mean = self.mean.expand(action.shape).to(action.dtype)
        std = self.std.expand(action.shape).to(action.dtype)
        noise = torch.normal(mean=mean, std=std, generator=self.generator)
        return self.spec[self.action_key].project(action + noise * self.sigma)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict.set(self.action_key, self._add_noise(tensordict.get(self.action_key)))


def snapshot_policy(policy: TensorDictSequential) -> TensorDictSequential:
    """A copy of ``policy`` = ``(actor, AdditiveGaussianModule)`` whose noise is seeded."""
    actor, noise = policy
    if not isinstance(noise, AdditiveGaussianModule):
        raise TypeError(f"expected (actor, AdditiveGaussianModule), got a {type(noise).__name__}")
    seeded = SeededGaussianNoise(
        spec=noise.spec[noise.action_key],
        sigma_init=float(noise.sigma),
        sigma_end=float(noise.sigma),
        annealing_num_steps=1,
        action_key=noise.action_key,
    )
    return TensorDictSequential(copy.deepcopy(actor), seeded)


class PrefetchCollector:
    """A TorchRL ``Collector`` iterated one batch ahead on a thread; see the module doc.

    Args:
        make_collector: builds the ``Collector`` from the policy it is given.
        policy: ``(actor, AdditiveGaussianModule)``, the actor being the learner's (trained in
            place): the collector gets a copy (:func:`snapshot_policy`).
        seed: of the exploration noise (:meth:`set_seed` re-seeds it with the envs).
    """

    def __init__(
        self,
        make_collector: Callable[[TensorDictModule], Collector],
        policy: TensorDictSequential,
        seed: int = 0,
    ) -> None:
        self.policy = snapshot_policy(policy)
        self.policy[1].generator.manual_seed(seed)
        self._source = TensorDict.from_module(policy[0])
        self._copy = TensorDict.from_module(self.policy[0]).data
        self.collector = make_collector(self.policy)
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="collector")

    def set_seed(self, seed: int) -> int:
        """Seed the envs (TorchRL) and the exploration noise."""
        self.policy[1].generator.manual_seed(seed)
        return self.collector.set_seed(seed)

    def update_policy_weights_(self) -> None:
        """Copy the learner's actor into the collection policy (call only between batches)."""
        self._copy.update_(self._source.data)

    def __iter__(self) -> Iterator[TensorDictBase]:
        batches = iter(self.collector)
        random_frames = int(getattr(self.collector, "init_random_frames", 0) or 0)
        frames, pending = 0, self._pool.submit(next, batches, None)
        while True:
            batch = pending.result()
            if batch is None:
                return
            frames += batch.numel()
            # The thread is idle here: the weights of the learner's last finished round.
            self.update_policy_weights_()
            if frames < random_frames:
                # The next batch's random actions draw from the global generator, which the
                # caller's side uses too (an evaluation reseeds it inside a fork): collected
                # after this batch is used, not beside it, its draws keep their order.
                yield batch
                pending = self._pool.submit(next, batches, None)
            else:
                pending = self._pool.submit(next, batches, None)
                yield batch

    def shutdown(self) -> None:
        self._pool.shutdown(wait=True)
        self.collector.shutdown()
