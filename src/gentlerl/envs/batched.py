"""N hands in one TorchRL env (batch size ``[N]``), their physics on a thread pool.

Each hand is a :class:`~gentlerl.envs.environment.HandEnvironment` built exactly as the single
env's (same task classes, same defaults). A step runs every hand's ``begin_step`` (the task's
action rules) on the calling thread, then the MuJoCo steps of all hands on ``num_threads`` threads
(``mujoco.mj_step`` releases the GIL; the ``touch_grid`` plugin keeps its state per ``MjData``),
then every hand's ``end_step`` (observations, reward, termination, time limit). The calling
thread steps one share of the hands itself, so ``num_threads=2`` starts one pool thread.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl._utils import seed_generator
from torchrl.envs import EnvBase

from gentlerl import keys
from gentlerl.envs.environment import HandEnvironment
from gentlerl.envs.rendering import render
from gentlerl.envs.torchrl_env import (
    FLAG_KEYS,
    NotPicklable,
    hand_specs,
    hand_tensordict,
    step_flags,
    step_limit,
)


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def check_num_threads(num_threads: int | None, num_envs: int) -> int:
    """``num_threads`` validated (default ``min(num_envs, cores)``); warns above the core count."""
    cores = available_cores()
    if num_threads is None:
        return max(1, min(num_envs, cores))
    if not (isinstance(num_threads, int | np.integer) and num_threads >= 1):
        raise ValueError(f"num_threads must be an integer >= 1, got {num_threads!r}")
    if num_threads > cores:
        warnings.warn(
            f"num_threads={num_threads} is more than the {cores} CPU cores available: the physics "
            "threads will contend for them",
            stacklevel=3,
        )
    return min(int(num_threads), num_envs)  # a thread without a hand would idle


class BatchedHandEnv(NotPicklable, EnvBase):
    """``len(dm_envs)`` hands as one TorchRL env with batch size ``[N]``; see the module doc.

    Keys, shapes (with a leading ``N``), dtypes and task rules are those of
    :class:`~gentlerl.envs.HandEnv`. Resets are per hand (the ``"_reset"`` mask that TorchRL's
    collectors pass); hand ``i`` is seeded with the ``i``-th seed of TorchRL's ``seed_generator``
    chain from ``seed``, as ``ParallelEnv`` seeds its workers (hand 0: ``seed`` itself).
    """

    def __init__(
        self,
        dm_envs: Sequence[HandEnvironment],
        *,
        num_threads: int | None = None,
        device: str | torch.device = "cpu",
        from_pixels: bool = False,
        pixel_size: int = 84,
    ) -> None:
        if len(dm_envs) < 1:
            raise ValueError(f"num_envs must be >= 1 (hands), got {len(dm_envs)}")
        n = len(dm_envs)
        self.num_threads = check_num_threads(num_threads, n)
        super().__init__(device=device, batch_size=torch.Size([n]))
        self.dm_envs = list(dm_envs)
        self.from_pixels = from_pixels
        self.pixel_size = pixel_size
        specs = hand_specs(device, from_pixels, pixel_size)
        self.observation_spec = specs["observation"].expand(n)
        self.action_spec = specs["action"].expand(n, *specs["action"].shape)
        self.reward_spec = specs["reward"].expand(n, *specs["reward"].shape)
        self.full_done_spec = specs["done"].expand(n)
        # Contiguous shares of the hands, one per thread; the calling thread takes the first.
        self._shares = [s.tolist() for s in np.array_split(np.arange(n), self.num_threads)]
        self._pool = ThreadPoolExecutor(self.num_threads - 1) if self.num_threads > 1 else None
        self.is_closed = False  # EnvBase starts "closed"; open, ``__del__`` and collectors close it

    @property
    def num_envs(self) -> int:
        return len(self.dm_envs)

    @property
    def time_limit(self) -> int:
        """Control steps per episode (every hand has the same limit)."""
        return step_limit(self.dm_envs[0])

    # -- stepping ------------------------------------------------------------------------
    def _physics(self, hands: list[int], stepping: list[bool]) -> None:
        for i in hands:
            if stepping[i]:
                self.dm_envs[i].step_physics()

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get(keys.ACTION).detach().cpu().numpy()
        # "_step" (TorchRL's partial steps, e.g. rollout(break_when_all_done=True)): hands left
        # out keep their state; TorchRL ignores their rows of the output.
        partial = tensordict.get("_step", None)
        active = [True] * self.num_envs if partial is None else partial.reshape(-1).tolist()
        # A hand stepped past its episode's end without a reset starts anew (as dm_control does).
        stepping = [a and not env.needs_reset for a, env in zip(active, self.dm_envs, strict=True)]
        for env, action, go in zip(self.dm_envs, actions, stepping, strict=True):
            if go:
                env.begin_step(action)  # raises on a bad action before any physics runs
        futures = [self._pool.submit(self._physics, s, stepping) for s in self._shares[1:]]
        self._physics(self._shares[0], stepping)
        for future in futures:
            future.result()
        flags = np.zeros((self.num_envs, len(FLAG_KEYS)), dtype=bool)
        reward = np.zeros((self.num_envs, 1), dtype=np.float32)
        for i, env in enumerate(self.dm_envs):
            if stepping[i]:
                reward[i, 0], discount = env.end_step()
                flags[i] = step_flags(env, discount)
            elif active[i]:
                env.reset()
        return self._output(flags, reward)

    def _step_proc_data(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        """``_step`` already writes every done key and a ``[N, 1]`` reward."""
        return next_tensordict

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        hands = range(self.num_envs) if mask is None else mask.reshape(-1).nonzero()[:, 0].tolist()
        for i in hands:
            self.dm_envs[i].reset()
        # Rows not reset are ignored by TorchRL (it keeps their current values).
        flags = np.zeros((self.num_envs, len(FLAG_KEYS)), dtype=bool)
        flags[:, 0] = [env.task.success for env in self.dm_envs]
        flags[:, 1] = [env.task.broken for env in self.dm_envs]
        return self._output(flags, None)

    def _output(self, flags: np.ndarray, reward: np.ndarray | None) -> TensorDictBase:
        buffer = np.stack([env.task.buffer for env in self.dm_envs])
        extra = {}
        if self.from_pixels:
            extra[keys.PIXELS] = torch.from_numpy(
                np.stack([self.render(i) for i in range(len(flags))])
            )
        td = hand_tensordict(buffer, flags, reward, extra)
        return td if self.device.type == "cpu" else td.to(self.device)

    def render(
        self, index: int = 0, height: int | None = None, width: int | None = None
    ) -> np.ndarray:
        """An RGB frame ``[H, W, 3]`` of hand ``index`` from the side camera (needs OpenGL)."""
        physics = self.dm_envs[index].physics
        return render(physics, height or self.pixel_size, width or self.pixel_size, "side")

    # -- seeds and closing ---------------------------------------------------------------
    def _seeds(self, seed: int) -> list[int]:
        """``num_envs + 1`` seeds: one per hand and the next free one (``seed_generator`` chain)."""
        seeds = [seed]
        for _ in range(self.num_envs):
            seeds.append(seed_generator(seeds[-1]))
        return seeds

    def _set_seed(self, seed: int | None) -> None:
        seeds = [None] * self.num_envs if seed is None else self._seeds(seed)
        for env, s in zip(self.dm_envs, seeds, strict=False):
            env.task._random = np.random.RandomState(s)

    def set_seed(self, seed: int | None = None, static_seed: bool = False) -> int | None:
        """Seed hand ``i`` with the ``i``-th seed of the chain; returns the next free seed."""
        self._set_seed(seed)
        return seed if seed is None or static_seed else self._seeds(seed)[-1]

    def close(self, *, raise_if_closed: bool = True) -> None:
        """Stop the threads; free every hand's physics and GL context now."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if not self.is_closed:
            for env in self.dm_envs:
                env.physics.free()
        super().close(raise_if_closed=raise_if_closed)
