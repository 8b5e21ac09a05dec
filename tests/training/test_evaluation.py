"""Evaluation: a batched env runs its hands' episodes at once, with the single env's numbers."""

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl._utils import seed_generator
from torchrl.envs import TransformedEnv

from gentlerl.training.evaluation import episode_stats, evaluate, summarize_episodes
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


def _episode(impacts, rewards):
    """A [T] episode as rollout_episodes returns it: impacts [T, sites] (N), task rewards [T]."""
    impact = torch.tensor(impacts)
    nxt = {"impact": impact, "reward": torch.tensor(rewards).unsqueeze(-1)}
    return TensorDict({"next": TensorDict(nxt, [len(rewards)])}, [len(rewards)])


def test_with_a_tolerance_an_episode_has_its_cost_in_steps_of_violation():
    # T = 2 N, two sites. Step costs min(1, sum relu(m - 2) / 2):
    #   [1, 1.5] -> 0; [3, 1] -> 0.5; [5, 4] -> min(1, 1.5 + 1) = 1; [2, 2.5] -> 0.25
    episode = _episode([[1.0, 1.5], [3.0, 1.0], [5.0, 4.0], [2.0, 2.5]], [0.0, 1.0, 1.0, 0.5])
    assert episode_stats(episode) == {"max_impact": 5.0, "return": 2.5}  # no tolerance: no cost
    assert episode_stats(episode, tolerance=2.0)["cost"] == 1.75
    # T = 20 mN (the same impacts in a unit 1000x smaller, T stated in it): the same cost
    milli = _episode(
        [[1e3 * m for m in s] for s in [[1, 1.5], [3, 1], [5, 4], [2, 2.5]]], [0.0] * 4
    )
    assert episode_stats(milli, tolerance=2000.0)["cost"] == 1.75
    calm = _episode([[0.5, 0.5]] * 3, [1.0] * 3)
    summary, per_episode = summarize_episodes([episode, calm], tolerance=2.0)
    assert [e["cost"] for e in per_episode] == [1.75, 0.0]
    assert summary["cost"] == 0.875 and summary["return"] == 2.75
    assert "cost" not in summarize_episodes([episode, calm])[0]
