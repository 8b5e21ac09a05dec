"""What an env's specs tell the agent (``gentlerl.rewards.specs``)."""

import pytest
from torchrl.envs import RenameTransform, TransformedEnv

from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.specs import check_env_keys, episode_steps
from tests.toy_env import ToyHandEnv


def test_missing_env_keys_are_reported_before_training():
    env = ToyHandEnv()
    rewards = IntrinsicRewards("r+rf", GentlenessConfig(), obs_dim=63, action_dim=20,
                               feature_shapes={})  # fmt: skip
    check_env_keys(
        env, rewards.transform, rewards.reward_keys
    )  # the toy env has the hand env's keys
    no_touch = TransformedEnv(ToyHandEnv(), RenameTransform(["touch"], ["force"]))
    with pytest.raises(ValueError, match="ImpactPenalty reads 'touch', which the env's spec lacks"):
        check_env_keys(no_touch, rewards.transform, rewards.reward_keys)
    no_observation = TransformedEnv(ToyHandEnv(), RenameTransform(["observation"], ["state"]))
    with pytest.raises(ValueError, match=r"key\(s\) \['observation'\] needed by the run"):
        check_env_keys(no_observation, rewards.transform, rewards.reward_keys)
    # success / broken are optional (an external env has neither): judged by its return
    no_outcomes = TransformedEnv(ToyHandEnv(), RenameTransform(["success", "broken"], ["a", "b"]))
    check_env_keys(no_outcomes, rewards.transform, rewards.reward_keys)


def test_episode_steps_reads_the_env_time_limit_else_the_default():
    env = ToyHandEnv()
    assert episode_steps(env) == env.time_limit
    no_limit = TransformedEnv(ToyHandEnv())  # a wrapper that names no time_limit of its own
    assert episode_steps(no_limit, default=17) == 17
