"""A tiny deterministic env with the hand env's keys and shapes, for transform tests.

Joint positions integrate the action; the fingertip force of site i grows with joint i pressing
past 0.5 (a "wall"), so pressing actions produce impacts.
"""

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs import EnvBase

from gentlerl import keys


class ToyHandEnv(EnvBase):
    def __init__(self, stiffness: float = 20.0, seed: int = 0):
        super().__init__(device="cpu", batch_size=torch.Size([]))
        self.stiffness = stiffness
        self.observation_spec = Composite(
            {
                keys.OBSERVATION: Unbounded((63,)),
                keys.JOINT_POS: Unbounded((24,)),
                keys.JOINT_VEL: Unbounded((24,)),
                keys.TOUCH: Unbounded((5, 3)),
            }
        )
        self.action_spec = Bounded(-1.0, 1.0, (20,))
        self.reward_spec = Unbounded((1,))
        self._set_seed(seed)

    def _obs(self, pos, vel):
        press = (pos[:5] - 0.5).clamp_min(0.0) * self.stiffness
        touch = torch.stack([press, 0.1 * press, 0.0 * press], -1)
        obs = torch.cat([pos, vel, touch.flatten()])
        return {keys.JOINT_POS: pos, keys.JOINT_VEL: vel, keys.TOUCH: touch, keys.OBSERVATION: obs}

    def _reset(self, tensordict=None):
        self._pos = torch.zeros(24)
        return TensorDict(self._obs(self._pos, torch.zeros(24)), [])

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict[keys.ACTION]
        vel = torch.zeros(24)
        vel[:20] = 0.1 * action
        self._pos = self._pos + vel
        out = self._obs(self._pos, vel)
        out.update(
            reward=torch.zeros(1),
            done=torch.zeros(1, dtype=torch.bool),
            terminated=torch.zeros(1, dtype=torch.bool),
        )
        return TensorDict(out, [])

    def _set_seed(self, seed):
        self.rng = torch.Generator().manual_seed(seed or 0)
