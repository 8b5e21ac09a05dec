"""The hand env for TorchRL: an ``EnvBase`` around the dm_control environment.

A thin, allocation-light wrapper (``torch.from_numpy`` views, pre-built specs) rather than
``DMControlWrapper``, so that it can also expose ``success`` / ``broken`` and the flat
``observation`` the learner reads.
"""

from __future__ import annotations

import numpy as np
import torch
from dm_control.rl import control
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from gentlerl import keys
from gentlerl.envs.assets import CHANNELS, GRID, TOUCH_SITES
from gentlerl.envs.hand import FLAT_SIZE, N_ACTUATORS, OBS_SLICES
from gentlerl.envs.rendering import render

N_SITES = len(TOUCH_SITES)
_SCALAR = torch.Size([])


def _flag() -> Categorical:
    return Categorical(2, (1,), dtype=torch.bool)


class HandEnv(EnvBase):
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
        dm_env: control.Environment,
        *,
        device: str | torch.device = "cpu",
        from_pixels: bool = False,
        pixel_size: int = 84,
    ) -> None:
        super().__init__(device=device, batch_size=torch.Size([]))
        self.dm_env = dm_env
        self.from_pixels = from_pixels
        self.pixel_size = pixel_size
        obs = {
            keys.JOINT_POS: Unbounded((24,), device=device),
            keys.JOINT_VEL: Unbounded((24,), device=device),
            keys.TOUCH: Unbounded((N_SITES, CHANNELS), device=device),
            keys.TOUCH_GRID: Unbounded((N_SITES, CHANNELS, *GRID), device=device),
            keys.ACTUATOR_FORCE: Unbounded((N_ACTUATORS,), device=device),
            keys.OBSERVATION: Unbounded((48 + N_SITES * CHANNELS,), device=device),
            keys.SUCCESS: _flag(),
            keys.BROKEN: _flag(),
        }
        if from_pixels:
            obs[keys.PIXELS] = Bounded(0, 255, (pixel_size, pixel_size, 3), dtype=torch.uint8)
        self.observation_spec = Composite(obs)
        self.action_spec = Bounded(-1.0, 1.0, (20,), device=device)
        self.reward_spec = Unbounded((1,), device=device)
        self.full_done_spec = Composite(done=_flag(), terminated=_flag(), truncated=_flag())
        self.is_closed = False  # EnvBase starts "closed"; open, ``__del__`` and collectors close it

    def _output(self, flags: dict[str, bool]) -> TensorDictBase:
        """This step's tensordict: the task's float32 buffer as views, plus bool ``flags``."""
        task = self.dm_env.task
        buf = torch.from_numpy(task.buffer)  # float32, fresh each step: the views below own it
        out = {key: buf[where].view(shape) for key, (where, shape) in OBS_SLICES.items()}
        out[keys.OBSERVATION] = buf[:FLAT_SIZE].clone()  # not aliased with joint_pos & co.
        flags = {keys.SUCCESS: task.success, keys.BROKEN: task.broken, **flags}
        values = torch.tensor(list(flags.values()))  # one allocation for all [1] flags
        out.update((key, values[i : i + 1]) for i, key in enumerate(flags))
        if self.from_pixels:
            out[keys.PIXELS] = torch.from_numpy(self.render())
        td = TensorDict._new_unsafe(out, batch_size=_SCALAR)
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
        return self._output({})

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        # Shape and finiteness are checked by the task (ValueError naming the value).
        timestep = self.dm_env.step(tensordict.get(keys.ACTION).detach().cpu().numpy())
        last = timestep.last()
        terminated = last and timestep.discount == 0.0
        done = {
            keys.TERMINATED: terminated,
            keys.TRUNCATED: last and not terminated,
            keys.DONE: last,
        }
        td = self._output(done)
        td.set(keys.REWARD, torch.tensor([timestep.reward or 0.0], dtype=torch.float32))
        return td

    def _step_proc_data(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        """``_step`` already writes every done key and a ``[1]`` reward: skip the generic fix-ups."""
        return next_tensordict

    def _set_seed(self, seed: int | None) -> None:
        self.dm_env.task._random = np.random.RandomState(seed)
