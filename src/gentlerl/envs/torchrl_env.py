"""The hand env for TorchRL: an ``EnvBase`` around the dm_control environment.

A thin, allocation-light wrapper (``torch.from_numpy`` views, pre-built specs) rather than
``DMControlWrapper``, so that it can also expose ``success`` / ``broken`` and the flat
``observation`` the learner reads. :func:`hand_specs` and :func:`hand_tensordict` are shared with
the batched env (:mod:`gentlerl.envs.batched`), so one hand and N hands write the same data.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from gentlerl import keys
from gentlerl.envs.assets import CHANNELS, GRID, TOUCH_SITES
from gentlerl.envs.environment import HandEnvironment
from gentlerl.envs.hand import FLAT_SIZE, N_ACTUATORS, N_JOINTS, OBS_SLICES
from gentlerl.envs.rendering import render

N_SITES = len(TOUCH_SITES)
#: The bool ``[1]`` entries of every step, in the order of the flag array of :func:`hand_tensordict`.
FLAG_KEYS = (keys.SUCCESS, keys.BROKEN, keys.TERMINATED, keys.TRUNCATED, keys.DONE)
_NOT_DONE = (False, False, False)
_CPU = torch.device("cpu")


def _flag() -> Categorical:
    return Categorical(2, (1,), dtype=torch.bool)


def hand_specs(
    device: str | torch.device, from_pixels: bool, pixel_size: int
) -> dict[str, Composite | Bounded]:
    """Unbatched ``observation`` / ``action`` / ``reward`` / ``done`` specs of one hand."""
    obs = {
        keys.JOINT_POS: Unbounded((N_JOINTS,), device=device),
        keys.JOINT_VEL: Unbounded((N_JOINTS,), device=device),
        keys.TOUCH: Unbounded((N_SITES, CHANNELS), device=device),
        keys.TOUCH_GRID: Unbounded((N_SITES, CHANNELS, *GRID), device=device),
        keys.ACTUATOR_FORCE: Unbounded((N_ACTUATORS,), device=device),
        keys.OBSERVATION: Unbounded((FLAT_SIZE,), device=device),
        keys.SUCCESS: _flag(),
        keys.BROKEN: _flag(),
    }
    if from_pixels:
        obs[keys.PIXELS] = Bounded(0, 255, (pixel_size, pixel_size, 3), dtype=torch.uint8)
    return {
        "observation": Composite(obs),
        "action": Bounded(-1.0, 1.0, (N_ACTUATORS,), device=device),
        "reward": Unbounded((1,), device=device),
        "done": Composite(done=_flag(), terminated=_flag(), truncated=_flag()),
    }


def step_limit(env: HandEnvironment) -> int:
    """``env``'s time limit in control steps (dm_control keeps it as a float step count)."""
    return math.ceil(env._step_limit)


def step_flags(env: HandEnvironment, discount: float | None) -> tuple[bool, ...]:
    """``FLAG_KEYS`` after a step that returned ``discount`` (None: running, 0: terminated)."""
    task = env.task
    last = discount is not None
    terminated = last and discount == 0.0
    return task.success, task.broken, terminated, last and not terminated, last


def hand_tensordict(
    buffer: np.ndarray, flags: np.ndarray, reward: np.ndarray | None, extra: dict[str, Any]
) -> TensorDictBase:
    """One step of ``B`` hands (``B`` = ``buffer.shape[:-1]``, ``()`` for one hand).

    ``buffer``: fresh float32 ``[*B, OBS_SIZE]`` observation buffers (laid out as ``OBS_SLICES``;
    the tensors are views of it); ``flags``: bool ``[*B, 5]`` in :data:`FLAG_KEYS` order;
    ``reward``: float32 ``[*B, 1]`` (None at reset); ``extra``: further entries (``pixels``).
    """
    # Views are cut in numpy and wrapped by one ``from_numpy`` each: slicing a torch tensor costs
    # ~3 us per call, a numpy slice ~0.3 us, and this runs for every env step.
    batch = buffer.shape[:-1]
    out = {
        key: torch.from_numpy(buffer[..., where].reshape(*batch, *shape))
        for key, (where, shape) in OBS_SLICES.items()
    }
    # A copy, not aliased with joint_pos & co.
    out[keys.OBSERVATION] = torch.from_numpy(buffer[..., :FLAT_SIZE].copy())
    out.update((key, torch.from_numpy(flags[..., i : i + 1])) for i, key in enumerate(FLAG_KEYS))
    if reward is not None:
        out[keys.REWARD] = torch.from_numpy(reward)
    out.update(extra)
    # On the CPU, as its tensors: a tensordict without a device is cast (``.to``) whenever a
    # collector sets it into its own CPU tensordict, at every step.
    return TensorDict._new_unsafe(out, batch_size=torch.Size(batch), device=_CPU, nested=False)


class NotPicklable:
    """Refuses ``pickle`` in one line: a MuJoCo model unpickled in the same process frees its
    memory twice (the process aborts, "double free or corruption"). Processes build their own
    hands from a factory (``partial(make_env, task, ...)``), as TorchRL's collectors do."""

    def __reduce_ex__(self, protocol: object) -> object:
        raise TypeError(
            f"{type(self).__name__} cannot be pickled (its MuJoCo model would be freed twice): "
            "pass a factory, e.g. functools.partial(gentlerl.envs.make_env, task), instead"
        )


class HandEnv(NotPicklable, EnvBase):
    """TorchRL view of a :func:`gentlerl.envs.make_dm_env` environment.

    Writes float32 ``joint_pos`` [24], ``joint_vel`` [24], ``touch`` [5, 3], ``touch_grid``
    [5, 3, 4, 4], ``actuator_force`` [20], ``observation`` [63] (joint_pos, joint_vel, flattened
    touch), bool ``success`` / ``broken`` [1], ``reward`` [1]; the time limit is reported as
    ``truncated``, success and a broken block as ``terminated``. ``joint_pos`` ...
    ``actuator_force`` of one step are views of one fresh float32 buffer (one allocation per
    step); ``observation`` is a copy of its first 63 values.
    """

    def __init__(
        self,
        dm_env: HandEnvironment,
        *,
        device: str | torch.device = "cpu",
        from_pixels: bool = False,
        pixel_size: int = 84,
    ) -> None:
        super().__init__(device=device, batch_size=torch.Size([]))
        self.dm_env = dm_env
        self.from_pixels = from_pixels
        self.pixel_size = pixel_size
        specs = hand_specs(device, from_pixels, pixel_size)
        self.observation_spec = specs["observation"]
        self.action_spec = specs["action"]
        self.reward_spec = specs["reward"]
        self.full_done_spec = specs["done"]
        self.is_closed = False  # EnvBase starts "closed"; open, ``__del__`` and collectors close it

    @property
    def time_limit(self) -> int:
        """Control steps per episode (truncation after them)."""
        return step_limit(self.dm_env)

    def _output(self, flags: tuple[bool, ...], reward: float | None) -> TensorDictBase:
        extra = {keys.PIXELS: torch.from_numpy(self.render())} if self.from_pixels else {}
        td = hand_tensordict(
            self.dm_env.task.buffer,
            np.array(flags),
            None if reward is None else np.array([reward], dtype=np.float32),
            extra,
        )
        return td if self.device.type == "cpu" else td.to(self.device)

    def render(self, height: int | None = None, width: int | None = None) -> np.ndarray:
        """An RGB frame ``[H, W, 3]`` from the side camera (needs an OpenGL backend)."""
        return render(
            self.dm_env.physics, height or self.pixel_size, width or self.pixel_size, "side"
        )

    def close(self, *, raise_if_closed: bool = True) -> None:
        """Free the physics and its GL context now, not whenever the garbage collector runs."""
        if not self.is_closed:
            self.dm_env.physics.free()
        super().close(raise_if_closed=raise_if_closed)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        self.dm_env.reset()
        task = self.dm_env.task
        return self._output((task.success, task.broken, *_NOT_DONE), None)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        dm_env = self.dm_env
        if dm_env.needs_reset:  # stepped past the end without reset: dm_control starts anew
            dm_env.reset()
            return self._output((False,) * len(FLAG_KEYS), 0.0)
        # Shape and finiteness are checked by the task (ValueError naming the value).
        dm_env.begin_step(tensordict.get(keys.ACTION).numpy(force=True))  # detached, on the CPU
        dm_env.step_physics()
        reward, discount = dm_env.end_step()
        return self._output(step_flags(dm_env, discount), reward)

    def _step_proc_data(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        """``_step`` already writes every done key and a ``[1]`` reward: skip the generic fix-ups."""
        return next_tensordict

    def _set_seed(self, seed: int | None) -> None:
        self.dm_env.task._random = np.random.RandomState(seed)
