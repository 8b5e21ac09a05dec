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
from gentlerl.envs.rendering import render

N_SITES = len(TOUCH_SITES)


def _flag() -> Categorical:
    return Categorical(2, (1,), dtype=torch.bool)


class HandEnv(EnvBase):
    """TorchRL view of a :func:`gentlerl.envs.make_dm_env` environment.

    Writes float32 ``joint_pos`` [24], ``joint_vel`` [24], ``touch`` [5, 3], ``touch_grid``
    [5, 3, 4, 4], ``observation`` [63] (joint_pos, joint_vel, flattened touch), bool ``success`` /
    ``broken`` [1], ``reward`` [1]; the time limit is reported as ``truncated``.
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

    def _observation(self, timestep: object) -> dict[str, torch.Tensor]:
        o = timestep.observation
        pos = torch.from_numpy(o["joint_pos"]).float()
        vel = torch.from_numpy(o["joint_vel"]).float()
        touch = torch.from_numpy(o["touch"]).float()
        task = self.dm_env.task
        out = {
            keys.JOINT_POS: pos,
            keys.JOINT_VEL: vel,
            keys.TOUCH: touch,
            keys.TOUCH_GRID: torch.from_numpy(o["touch_grid"]).float(),
            keys.OBSERVATION: torch.cat([pos, vel, touch.flatten()]),
            keys.SUCCESS: torch.tensor([task.success]),
            keys.BROKEN: torch.tensor([task.broken]),
        }
        if self.from_pixels:
            out[keys.PIXELS] = torch.from_numpy(self.render())
        return out

    def render(self, height: int | None = None, width: int | None = None) -> np.ndarray:
        """An RGB frame ``[H, W, 3]`` from the side camera (needs an OpenGL backend)."""
        return render(
            self.dm_env.physics, height or self.pixel_size, width or self.pixel_size, "side"
        )

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        return TensorDict(self._observation(self.dm_env.reset()), batch_size=[], device=self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get(keys.ACTION)
        if action.shape != (20,):
            raise ValueError(f"action must have shape (20,), got {tuple(action.shape)}")
        if not torch.isfinite(action).all():
            raise ValueError(f"action must be finite, got {action}")
        timestep = self.dm_env.step(action.detach().cpu().numpy())
        out = self._observation(timestep)
        last = timestep.last()
        terminated = last and timestep.discount == 0.0
        out[keys.REWARD] = torch.tensor([float(timestep.reward or 0.0)])
        out[keys.TERMINATED] = torch.tensor([terminated])
        out[keys.TRUNCATED] = torch.tensor([last and not terminated])
        out[keys.DONE] = torch.tensor([last])
        return TensorDict(out, batch_size=[], device=self.device)

    def _set_seed(self, seed: int | None) -> None:
        self.dm_env.task._random = np.random.RandomState(seed)
