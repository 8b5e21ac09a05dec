"""MultiHeadD4PGLoss in a plain TorchRL pipeline (no gentlerl training loop): Pendulum-v1.

Collector + TensorDictReplayBuffer + MultiStepTransform + HardUpdate around gentlerl's actor,
fused critic and loss. Pendulum returns lie in about [-1600, 0] per 200-step episode; a random
policy scores about -1200, a swing-up policy better than -400.
"""

import pytest
import torch
from torchrl.collectors import Collector
from torchrl.envs import Compose, DoubleToFloat, RewardScaling, TransformedEnv
from torchrl.envs.libs.gym import GymEnv
from torchrl.envs.transforms._action import ActionScaling
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.agent.learner import Learner
from gentlerl.data import make_replay_buffer
from gentlerl.models import make_actor, make_critic, make_exploration_policy
from gentlerl.objectives import MultiHeadD4PGLoss

pytest.importorskip("gymnasium")


def _env(seed):
    env = TransformedEnv(
        GymEnv("Pendulum-v1"),
        Compose(DoubleToFloat(), ActionScaling(), RewardScaling(loc=0.0, scale=0.1)),
    )
    env.set_seed(seed)
    return env


@pytest.mark.slow
def test_d4pg_swings_up_the_pendulum():
    torch.manual_seed(0)
    torch.set_num_threads(1)
    actor = make_actor(3, 1, (64, 64))
    critic = make_critic(3, 1, 1, (128, 128), 51, v_min=-100.0, v_max=5.0)
    # Scaled rewards lie in [-1.63, 0]: 3-step returns and values fit in [-100, 5].
    loss = MultiHeadD4PGLoss(actor, critic, reward_keys=[keys.REWARD])
    loss.set_keys(terminated=keys.NSTEP_TERMINATED)
    learner = Learner(loss, lr_actor=3e-4, lr_critic=3e-4, target_update_period=100)
    rb = make_replay_buffer(50_000, 128, n_steps=3, gamma=0.99)
    policy = make_exploration_policy(actor, sigma=0.3, action_dim=1)
    collector = Collector(
        lambda: _env(0), policy, frames_per_batch=200, total_frames=14_000, init_random_frames=2_000
    )
    for i, batch in enumerate(collector):
        rb.extend(batch)
        if i < 10:
            continue
        for _ in range(100):
            sample = rb.sample()
            learner.update(sample)
            rb.update_tensordict_priority(sample)
    collector.shutdown()
    env = _env(1)
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        returns = [10 * env.rollout(200, actor)["next", keys.REWARD].sum().item() for _ in range(5)]
    assert sum(returns) / len(returns) > -400, returns
