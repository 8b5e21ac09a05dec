"""Replay for the D4PG learner: TorchRL prioritised replay of n-step transitions, written by
:class:`NStepWriter` (the buffer itself holds ready transitions; :func:`make_nstep_transform` is
the step that turns a time-contiguous batch into them).

``MultiStepTransform`` sums every reward component over ``n_steps`` at write time and maps
``("next", obs)`` to the observation ``n`` steps ahead (``steps_to_next_obs`` holds the actual n,
shorter at episode ends). It leaves the done flags of step t untouched, so the bootstrap could be
taken from a terminal state; :class:`NStepTerminated` copies ``("next", "terminated")`` to
``("next", "nstep_terminated")``, which ``MultiStepTransform`` *does* gather from the window's last
step, and the loss reads that key (``loss.set_keys(terminated=keys.NSTEP_TERMINATED)``).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torchrl.data import (
    LazyTensorStorage,
    RandomSampler,
    TensorDictReplayBuffer,
)
from torchrl.data.replay_buffers.scheduler import LinearScheduler
from torchrl.envs.transforms import Compose, MultiStepTransform, Transform

from gentlerl import keys
from gentlerl.data.prioritized import TorchPrioritizedSampler
from gentlerl.data.windows import WINDOW, nstep_windows


class NStepTerminated(Transform):
    """Replay-buffer transform: on write, copy ``("next", "terminated")`` to ``("next", "nstep_terminated")``."""

    def __init__(self) -> None:
        super().__init__(
            in_keys_inv=[("next", keys.TERMINATED)], out_keys_inv=[("next", keys.NSTEP_TERMINATED)]
        )

    def _inv_call(self, tensordict: TensorDictBase) -> TensorDictBase:
        for src, dst in zip(self.in_keys_inv, self.out_keys_inv, strict=True):
            tensordict.set(dst, tensordict.get(src).clone())
        return tensordict


def make_replay_buffer(
    capacity: int,
    batch_size: int,
    *,
    prioritized: bool = True,
    alpha: float = 0.6,
    beta: float = 0.4,
    n_steps: int | None = 5,
    gamma: float = 0.99,
    reward_keys: Sequence[str] = (keys.REWARD,),
    device: str = "cpu",
) -> TensorDictReplayBuffer:
    """The agent's replay buffer: n-step transitions, prioritised by the loss's ``td_error``.

    Args:
        capacity: transitions kept (paper: 1M).
        batch_size: transitions per sample (paper: 256).
        prioritized: TorchRL's ``PrioritizedSampler`` logic (:class:`TorchPrioritizedSampler`) (priorities ``|td_error|^alpha``, importance
            weights with exponent ``beta``, see :func:`make_beta_scheduler`); uniform otherwise.
        n_steps, gamma: n-step returns of every key in ``reward_keys`` (Acme D4PG: n = 5, 0.99);
            ``n_steps=None``: the buffer stores what it is given (write through an
            :class:`NStepWriter`, which handles ``[B, T]`` batches and checkpoints its tail).
        device: where the transitions and the priority trees live (on a GPU the trees make no
            host read: :mod:`gentlerl.data.prioritized`).

    Write with ``rb.extend(batch)`` where ``batch`` is ``[T]`` or ``[B, T]`` time-contiguous
    (a collector batch); the last ``n_steps`` of each write wait for the next one.
    """
    sizes = (("capacity", capacity), ("batch_size", batch_size), ("n_steps", n_steps or 1))
    for name, value in sizes:
        if int(value) < 1:
            raise ValueError(f"{name} must be >= 1, got {value}")
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma}")
    if prioritized and not (alpha >= 0 and beta >= 0):
        raise ValueError(f"alpha and beta must be >= 0, got alpha={alpha}, beta={beta}")
    trees = None if torch.device(device).type == "cpu" else device  # TorchRL's default: CPU
    sampler = (
        TorchPrioritizedSampler(capacity, alpha=alpha, beta=beta, device=trees)
        if prioritized
        else RandomSampler()
    )
    transform = None if n_steps is None else make_nstep_transform(n_steps, gamma, reward_keys)
    return TensorDictReplayBuffer(
        storage=LazyTensorStorage(capacity, device=device),
        sampler=sampler,
        priority_key=keys.PRIORITY,
        transform=transform,
        batch_size=batch_size,
    )


def make_nstep_transform(n_steps: int, gamma: float, reward_keys: Sequence[str]) -> Compose:
    """``MultiStepTransform`` after :class:`NStepTerminated` (Compose inverts in reverse order)."""
    return Compose(
        MultiStepTransform(n_steps, gamma, reward_keys=list(reward_keys)), NStepTerminated()
    )


class NStepWriter:
    """Writes time-contiguous batches (``[T]``, or ``[B, T]``: B envs) as n-step transitions.

    TorchRL's ``MultiStepTransform`` computes the windows along the last (time) dim, keeping the
    last ``n_steps`` of each row for the next write; the flat buffer then gets the rows' ready
    transitions in order. :attr:`tail` (those last steps) is what a checkpoint needs to continue.

    With ``window_keys``, every transition also stores its window's raw steps (those entries of
    steps ``t .. t + n - 1``) under ``"window"`` (:func:`~gentlerl.data.windows.nstep_windows`),
    so that a model-based reward can be recomputed when the transition is sampled.
    """

    def __init__(
        self,
        rb: TensorDictReplayBuffer,
        n_steps: int,
        gamma: float,
        reward_keys: Sequence[str],
        window_keys: Sequence[NestedKey] = (),
    ) -> None:
        if rb.transform is not None and len(rb.transform):
            raise ValueError("NStepWriter needs a buffer without transforms (n_steps=None)")
        self.rb, self.n_steps = rb, n_steps
        self.window_keys = list(window_keys)
        self._make_transform = partial(make_nstep_transform, n_steps, gamma, list(reward_keys))
        self.transform = self._make_transform()
        self.tail: TensorDictBase | None = None

    def extend(self, batch: TensorDictBase) -> None:
        # The steps the transform holds back joined with the new ones, as MultiStepTransform
        # joins them: a write shorter than n_steps keeps earlier steps in the tail.
        joined = batch if self.tail is None else torch.cat([self.tail, batch], -1)
        self.tail = joined[..., -self.n_steps :].clone()
        ready = self.transform.inv(batch)
        if ready is not None:
            if self.window_keys:
                # The windows have one more batch dim than ``ready``: a collector's dim names
                # (["time"]) would be forced onto them.
                ready.names = None
                steps = joined.select(*self.window_keys)
                ready.set(WINDOW, nstep_windows(steps, self.n_steps, ready.shape[-1]))
            self.rb.extend(ready.reshape(-1))

    def state_dict(self) -> dict[str, TensorDictBase | None]:
        return {"tail": self.tail}

    def load_state_dict(self, state: dict[str, TensorDictBase | None]) -> None:
        """Continue after ``state["tail"]``, each row's last step marked truncated.

        The resumed collector starts new episodes, so the episodes running at checkpoint time end
        there: their pending transitions bootstrap from that step (as a time limit would), none
        lost and none summed across the cut. Writing the tail alone only primes the transform.
        """
        self.transform, self.tail = self._make_transform(), None
        if state["tail"] is not None:
            tail = state["tail"].clone()
            for key in (keys.DONE, keys.TRUNCATED):
                tail.get(("next", key))[..., -1, :] = True
            self.extend(tail)


def make_model_buffer(
    capacity: int, batch_size: int | None = None, device: str = "cpu"
) -> TensorDictReplayBuffer:
    """Uniform buffer of 1-step transitions for the dynamics / penalty / ICM models.

    Without ``batch_size`` every ``sample(n)`` names its size (the training loop draws a
    bootstrap batch of ``ensemble_size x model_batch_size`` for ensembles).
    """
    for name, value in (("capacity", capacity), ("batch_size", batch_size)):
        if value is not None and int(value) < 1:
            raise ValueError(f"{name} must be >= 1, got {value}")
    return TensorDictReplayBuffer(
        storage=LazyTensorStorage(capacity, device=device),
        sampler=RandomSampler(),
        batch_size=batch_size,
    )


def make_beta_scheduler(
    rb: TensorDictReplayBuffer, final_beta: float = 1.0, num_steps: int = 100_000
) -> LinearScheduler:
    """Anneal the importance-sampling exponent beta linearly to ``final_beta`` over ``num_steps``
    calls of ``scheduler.step()`` (Schaul et al. 2016)."""
    if not isinstance(rb.sampler, TorchPrioritizedSampler):
        raise ValueError("beta annealing needs a prioritised buffer (prioritized=True)")
    return LinearScheduler(rb, param_name="beta", final_value=final_beta, num_steps=num_steps)
