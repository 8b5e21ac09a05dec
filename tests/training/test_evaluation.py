"""Evaluation: a batched env runs its hands' episodes at once, with the single env's numbers."""

import torch
from tensordict.nn import TensorDictModule
from torchrl._utils import seed_generator
from torchrl.envs import TransformedEnv

from gentlerl.training.evaluation import evaluate
from gentlerl.transforms import ImpactPenalty


class _Press(torch.nn.Module):
    """Flex the index knuckle: the block is pressed with > 5 N in ~38 steps (regime "easy")."""

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        action = torch.zeros(*obs.shape[:-1], 20)
        action[..., 3] = 1.0
        return action


def _env(make_env, seed: int, num_envs: int | None = None):
    env = TransformedEnv(
        make_env("fragile", seed=seed, num_envs=num_envs, regime="easy"), ImpactPenalty()
    )
    env.set_seed(seed)
    return env


def test_batched_evaluation_equals_one_episode_per_single_env(hand_env):
    actor = TensorDictModule(_Press(), ["observation"], ["action"])
    summary, episodes = evaluate(_env(hand_env, 3, num_envs=3), actor, episodes=3, max_steps=1000)
    seeds = [3, seed_generator(3), seed_generator(seed_generator(3))]
    expected = [evaluate(_env(hand_env, s), actor, episodes=1, max_steps=1000)[1][0] for s in seeds]
    assert episodes == expected
    # fragile: a press succeeds with +5, once per episode (the repeated last rows are not summed).
    assert summary["success_rate"] == 1.0 and summary["return"] == 5.0
    assert 0.3 < summary["max_impact_mean"] < 3.0  # a gentle press, below the 3 N break
