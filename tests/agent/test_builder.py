"""AgentBuilder: every size read from the env's specs; the parts a runner asks for."""

import torch
from tensordict import TensorDict
from torchrl.envs import SerialEnv

from gentlerl import keys
from gentlerl.agent.builder import AgentBuilder
from gentlerl.training import make_config
from tests.toy_env import ToyHandEnv

TINY = dict(network={"actor_hidden": (8,), "critic_hidden": (8,), "num_atoms": 5},
            gentleness={"model_hidden": 8})  # fmt: skip


def test_sizes_come_from_the_env_specs_batch_dims_left_out():
    env = SerialEnv(2, ToyHandEnv)
    builder = AgentBuilder(make_config(**TINY), env)
    assert (builder.obs_dim, builder.action_dim) == (63, 20)
    assert builder.feature_shapes == {
        keys.JOINT_POS: (24,),
        keys.JOINT_VEL: (24,),
        keys.TOUCH: (5, 3),
    }


def test_parts_fit_together():
    builder = AgentBuilder(make_config(**TINY, replay={"batch_size": 4}), ToyHandEnv())
    rewards = builder.rewards
    learner = builder.make_learner()
    assert rewards.reward_keys == learner.loss.reward_keys == builder.reward_keys
    assert set(rewards.losses) == {"penalty"}  # r+rf+rsp learns the penalty ensemble only
    policy = builder.make_policy(learner)
    action = policy(TensorDict({keys.OBSERVATION: torch.randn(7, 63)}, [7]))[keys.ACTION]
    assert action.shape == (7, 20) and action.abs().max() <= 1.0
    writer, rb, schedule = builder.make_replay(total_updates=10)
    assert writer.rb is rb and (rb.transform is None or not len(rb.transform))
    assert schedule is not None and writer.n_steps == 5


def test_the_penalty_surprise_head_gets_its_own_per_step_bound():
    # r^sp's head spans +-3 x the discounted horizon of the env's episode (gamma 0.99).
    builder = AgentBuilder(make_config(**TINY), ToyHandEnv())
    horizon = (1 - 0.99**builder.horizon) / 0.01
    base = builder.supports
    cfg = make_config(**{**TINY, "network": {**TINY["network"], "penalty_surprise_bound": 3.0}})
    lows, highs = AgentBuilder(cfg, ToyHandEnv()).supports
    assert (lows[:2], highs[:2]) == (base[0][:2], base[1][:2])  # task and penalty unchanged
    assert lows[2] == -highs[2] and abs(highs[2] - 3.0 * horizon) < 1e-9
