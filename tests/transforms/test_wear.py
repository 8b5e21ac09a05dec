"""ForcePenalty and TorquePenalty: hand-computed rewards, specs, and their variants' critic heads."""

import math

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.variants import head_supports, reward_keys
from gentlerl.transforms import ForcePenalty, TorquePenalty
from tests.toy_env import ToyHandEnv


def _push(env, steps=10):
    # Joint 1 moves +0.1 per step and reaches the wall at 0.5 after 5 steps; then fingertip 1's
    # force grows by 2 N (+ 0.2 N tangential) per step and actuator 1 pushes back with 0.1 N m / N.
    action = torch.zeros(20)
    action[1] = 1.0
    return env.rollout(steps, policy=lambda td: td.set(keys.ACTION, action.expand(*td.shape, 20)))


def _acceptability_cost(x, lam1, lam2):
    return (1 - 1 / (1 + math.exp(lam1 * (x - lam2)))) * x


def test_force_penalty_on_env_is_the_level_not_the_increase():
    env = TransformedEnv(ToyHandEnv(), ForcePenalty(lam=(2.0, 4.0)))
    check_env_specs(env)
    assert keys.FORCE_PENALTY in env.reward_keys
    penalty = _push(env)["next", keys.FORCE_PENALTY][:, 0]
    # Step k >= 5 holds 2.2 (k - 4) N in total on fingertip 1: the cost keeps growing while the
    # impact (the increase, 2.2 N each step) stays the same.
    expected = [-_acceptability_cost(2.2 * max(k - 4, 0), 2.0, 4.0) for k in range(10)]
    torch.testing.assert_close(penalty, torch.tensor(expected), atol=1e-4, rtol=0)


def test_torque_penalty_on_env_charges_the_actuators_effort():
    env = TransformedEnv(ToyHandEnv(), TorquePenalty(lam=(4.0, 0.5)))
    check_env_specs(env)
    penalty = _push(env)["next", keys.TORQUE_PENALTY][:, 0]
    # Actuator 1: 0.1 N m per N of fingertip 1's normal force, 2 (k - 4) N at step k.
    expected = [-_acceptability_cost(0.2 * max(k - 4, 0), 4.0, 0.5) for k in range(10)]
    torch.testing.assert_close(penalty, torch.tensor(expected), atol=1e-4, rtol=0)


def test_custom_keys_batches_and_bad_arguments():
    td = TensorDict({"effort": torch.zeros(2, 3), "next": {"effort": -torch.ones(2, 3)}}, [2])
    out = TorquePenalty((4.0, 1.0), in_keys=["effort"], out_keys=["rt"])(td)
    torch.testing.assert_close(out["next", "rt"], torch.full((2, 1), -1.5))  # 3 x 0.5
    with pytest.raises(ValueError, match="ForcePenalty reads one key"):
        ForcePenalty(in_keys=["a", "b"])
    with pytest.raises(ValueError, match="TorquePenalty lam"):
        TorquePenalty((-1.0, 1.0))


@pytest.mark.parametrize(
    ("variant", "key"), [("r+rf+rsp+rF", keys.FORCE_PENALTY), ("r+rf+rsp+rt", keys.TORQUE_PENALTY)]
)
def test_variants_add_their_head_and_run_on_the_hand_env(variant, key):
    from gentlerl.envs import make_env

    heads = [keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE, key]
    assert reward_keys(variant) == heads
    # Never positive: with a bounded support the head's values stop at 0, like the impact penalty's.
    assert head_supports(heads, v_min=-10.0, v_max=10.0, bounded=True)[1] == [10.0, 0.0, 10.0, 0.0]
    settings = GentlenessConfig(model_hidden=16, ensemble_size=2, reward_delay=0)
    features = {keys.JOINT_POS: (24,), keys.JOINT_VEL: (24,), keys.TOUCH: (5, 3)}
    rewards = IntrinsicRewards(
        variant, settings, obs_dim=63, action_dim=20, feature_shapes=features
    )
    env = TransformedEnv(make_env("touch", seed=0), rewards.transform)
    try:
        check_env_specs(env)
        rollout = env.rollout(5)
    finally:
        env.close()
    assert rollout["next", key].shape == (5, 1) and (rollout["next", key] <= 0).all()
