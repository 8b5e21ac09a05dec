"""A tiny deterministic env with the hand env's keys and shapes, for transform and loop tests.

Joint positions integrate the action; the fingertip force of site i grows with joint i pressing
past 0.5 (a "wall"), so pressing actions produce impacts, and actuator i pushes back with 0.1 N m
per N of that force; pressing fingertip 0 with more than 5 N is a success (+1, terminated);
episodes are truncated after ``time_limit`` steps.
"""

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from gentlerl import keys


class ToyHandEnv(EnvBase):
    def __init__(self, stiffness: float = 20.0, seed: int = 0, time_limit: int = 50):
        super().__init__(device="cpu", batch_size=torch.Size([]))
        self.stiffness = stiffness
        self.time_limit = time_limit
        self.observation_spec = Composite(
            {
                keys.OBSERVATION: Unbounded((63,)),
                keys.JOINT_POS: Unbounded((24,)),
                keys.JOINT_VEL: Unbounded((24,)),
                keys.TOUCH: Unbounded((5, 3)),
                keys.ACTUATOR_FORCE: Unbounded((20,)),
                keys.SUCCESS: Categorical(2, (1,), dtype=torch.bool),
                keys.BROKEN: Categorical(2, (1,), dtype=torch.bool),
            }
        )
        self.action_spec = Bounded(-1.0, 1.0, (20,))
        self.reward_spec = Unbounded((1,))
        flag = Categorical(2, (1,), dtype=torch.bool)
        self.full_done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone()
        )
        self._set_seed(seed)

    def _obs(self, pos, vel):
        press = (pos[:5] - 0.5).clamp_min(0.0) * self.stiffness
        touch = torch.stack([press, 0.1 * press, 0.0 * press], -1)
        obs = torch.cat([pos, vel, touch.flatten()])
        actuator_force = torch.cat([0.1 * press, torch.zeros(15)])
        success = touch[0, :1] > 5.0  # fingertip 0 "pressed with more than 5 N"
        return {
            keys.JOINT_POS: pos,
            keys.JOINT_VEL: vel,
            keys.TOUCH: touch,
            keys.ACTUATOR_FORCE: actuator_force,
            keys.OBSERVATION: obs,
            keys.SUCCESS: success,
            keys.BROKEN: torch.zeros(1, dtype=torch.bool),
        }

    def _reset(self, tensordict=None):
        self._pos = torch.zeros(24)
        self._t = 0
        return TensorDict(self._obs(self._pos, torch.zeros(24)), [])

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict[keys.ACTION]
        vel = torch.zeros(24)
        vel[:20] = 0.1 * action
        self._pos = self._pos + vel
        self._t += 1
        out = self._obs(self._pos, vel)
        terminated = out[keys.SUCCESS].clone()
        truncated = torch.tensor([self._t >= self.time_limit]) & ~terminated
        out.update(
            reward=terminated.float(),
            done=terminated | truncated,
            terminated=terminated,
            truncated=truncated,
        )
        return TensorDict(out, [])

    def _set_seed(self, seed):
        self.rng = torch.Generator().manual_seed(seed or 0)
