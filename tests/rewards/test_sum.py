"""``SumRewards`` by hand: the specs it leaves an env with (one reward; the components and the
task's reward as observations, each with its own spec), the errors it names, its order check."""

import pytest
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs import EnvBase, RewardScaling, RewardSum, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.rewards import SumRewards


class TwoRewardEnv(EnvBase):
    """A float64 task reward ``[1]`` (1 per step) and a penalty ``[1]`` in ``[-1, 0]`` (-0.25
    per step), episodes of 3 steps."""

    def __init__(self) -> None:
        super().__init__(device="cpu", batch_size=torch.Size([]))
        self.observation_spec = Composite(observation=Unbounded((2,)))
        self.action_spec = Unbounded((1,))
        self.full_reward_spec = Composite(
            reward=Unbounded((1,), dtype=torch.float64),
            penalty=Bounded(-1.0, 0.0, (1,), dtype=torch.float64),
        )
        self._t = 0

    def _reset(self, tensordict=None):
        self._t = 0
        return TensorDict({"observation": torch.zeros(2)}, [])

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._t += 1
        done = torch.tensor([self._t >= 3])
        return TensorDict(
            {
                "observation": torch.full((2,), float(self._t)),
                "reward": torch.ones(1, dtype=torch.float64),
                "penalty": torch.full((1,), -0.25, dtype=torch.float64),
                "done": done,
                "terminated": done.clone(),
            },
            [],
        )

    def _set_seed(self, seed):
        return seed


def test_the_summed_env_has_one_reward_spec_shaped_and_typed_as_the_first_component():
    env = TransformedEnv(TwoRewardEnv(), SumRewards(["reward", "penalty"]))
    check_env_specs(env)
    rewards = env.full_reward_spec
    assert list(rewards.keys()) == ["reward"]
    assert rewards["reward"] == Unbounded((1,), dtype=torch.float64, device="cpu")
    # the components are observations now, each with the spec the env gave it
    observations = env.full_observation_spec
    assert observations["penalty"] == Bounded(-1.0, 0.0, (1,), dtype=torch.float64, device="cpu")
    assert observations[keys.TASK_REWARD] == Unbounded((1,), dtype=torch.float64, device="cpu")
    rollout = env.rollout(3)
    assert rollout["next", "reward"].dtype == torch.float64
    torch.testing.assert_close(
        rollout["next", "reward"], torch.full((3, 1), 0.75, dtype=torch.float64)
    )
    # zero after a reset, as their observation specs say
    reset = env.reset()
    assert reset["penalty"].item() == 0 and reset[keys.TASK_REWARD].item() == 0


def test_one_component_sums_to_itself_and_keeps_its_spec():
    env = TransformedEnv(TwoRewardEnv(), SumRewards(["reward"], weights=[2.0]))
    assert list(env.full_reward_spec.keys()) == ["reward", "penalty"]  # penalty not summed
    assert env.full_reward_spec["reward"] == Unbounded((1,), dtype=torch.float64, device="cpu")
    assert keys.TASK_REWARD in env.full_observation_spec.keys()
    assert "penalty" not in env.full_observation_spec.keys()
    rollout = env.rollout(2)
    assert rollout["next", "reward"].flatten().tolist() == [2.0, 2.0]


def test_a_component_the_env_does_not_write_is_named_with_the_rewards_there():
    with pytest.raises(
        KeyError,
        match=r"SumRewards sums \['bonus'\], which the env's reward spec lacks; it has "
        r"\['penalty', 'reward'\] \(append the reward transforms first\)",
    ):
        _ = TransformedEnv(TwoRewardEnv(), SumRewards(["reward", "bonus"])).full_reward_spec


def test_a_tensordict_without_next_is_refused_naming_its_keys():
    td = TensorDict({"reward": torch.ones(1), "penalty": torch.zeros(1)})
    with pytest.raises(
        ValueError,
        match=r"^SumRewards needs a transition: a tensordict with a 'next' entry, got keys "
        r"\['penalty', 'reward'\]$",
    ):
        SumRewards(["reward", "penalty"])(td)


def test_a_missing_component_and_a_misshaped_one_are_named():
    td = TensorDict({"next": {"reward": torch.ones(1), "bonus": torch.ones(1)}})
    with pytest.raises(
        KeyError,
        match=r"SumRewards sums 'penalty', which the tensordict's 'next' lacks; it has "
        r"\['bonus', 'reward', 'task_reward'\]",
    ):
        SumRewards(["reward", "penalty"])(td)
    td = TensorDict({"next": {"reward": torch.ones(1), "penalty": torch.ones(2)}})
    with pytest.raises(
        ValueError, match=r"^SumRewards: 'penalty' is shaped \(2,\), the others \(1,\)$"
    ):
        SumRewards(["reward", "penalty"])(td)


def test_bad_keys_and_weights_are_refused_in_one_line():
    with pytest.raises(
        ValueError,
        match=r"^SumRewards: task_key 'penalty' is also one of \['reward', 'penalty'\]$",
    ):
        SumRewards(["reward", "penalty"], task_key="penalty")
    reward_sum = SumRewards(["reward", "penalty"])
    with pytest.raises(
        ValueError, match=r"^SumRewards: a weight must be a finite number, got inf$"
    ):
        reward_sum.set_weight("penalty", float("inf"))
    with pytest.raises(KeyError, match=r"'bonus' is not one of the summed keys"):
        reward_sum.set_weight("bonus", 1.0)
    reward_sum.set_weight("penalty", 4.0)
    td = TensorDict({"next": {"reward": torch.ones(1), "penalty": -0.25 * torch.ones(1)}})
    assert reward_sum(td)["next", "reward"].item() == 1.0 - 4.0 * 0.25


def test_a_transform_after_the_sum_that_reads_the_reward_is_no_reward_sum_and_runs():
    """Only a RewardSum of the summed key is refused: a RewardScaling of it is an agent's own."""
    env = TransformedEnv(TwoRewardEnv(), SumRewards(["reward", "penalty"]))
    env.append_transform(RewardScaling(loc=0.0, scale=2.0, in_keys=["reward"]))
    rollout = env.rollout(3)
    torch.testing.assert_close(
        rollout["next", "reward"], torch.full((3, 1), 1.5, dtype=torch.float64)
    )
    refused = TransformedEnv(TwoRewardEnv(), SumRewards(["reward", "penalty"]))
    refused.append_transform(RewardSum(in_keys=["reward"]))
    with pytest.raises(ValueError, match=r"RewardSum after SumRewards sums the combined 'reward'"):
        refused.rollout(2)


def test_the_order_is_checked_once_at_the_first_step_not_at_every_step(monkeypatch):
    reward_sum = SumRewards(["reward", "penalty"])
    env = TransformedEnv(TwoRewardEnv(), reward_sum)
    calls = []
    check = reward_sum._check_order

    def counted():
        calls.append(1)
        check()

    monkeypatch.setattr(reward_sum, "_check_order", counted)
    env.rollout(3)
    assert len(calls) == 1


class BatchedSpecEnv(EnvBase):
    """Specs only: 2 envs in a batch on the ``meta`` device (an accelerator's stand-in: a device
    other than the default one, with no data), a reward and a penalty ``[2, 1]``."""

    def __init__(self) -> None:
        super().__init__(device="meta", batch_size=torch.Size([2]))
        self.observation_spec = Composite(observation=Unbounded((2, 3)), shape=(2,))
        self.action_spec = Unbounded((2, 1))
        self.full_reward_spec = Composite(
            reward=Unbounded((2, 1)), penalty=Unbounded((2, 1)), shape=(2,)
        )

    def _reset(self, tensordict=None):
        raise NotImplementedError

    def _step(self, tensordict):
        raise NotImplementedError

    def _set_seed(self, seed):
        return seed


def test_the_summed_reward_spec_keeps_the_envs_batch_and_device():
    env = TransformedEnv(BatchedSpecEnv(), SumRewards(["reward", "penalty"]))
    expected = Unbounded((2, 1), device="meta")
    assert env.full_reward_spec["reward"] == expected
    assert env.full_observation_spec["penalty"] == expected
    assert env.full_observation_spec[keys.TASK_REWARD] == expected


def test_weights_replaced_by_a_list_of_another_length_are_refused_at_the_next_sum():
    """``weights`` is a public list: one weight too few must not drop a component silently."""
    reward_sum = SumRewards(["reward", "penalty"])
    reward_sum.weights = [1.0]
    td = TensorDict({"next": {"reward": torch.ones(1), "penalty": -torch.ones(1)}})
    with pytest.raises(ValueError, match="zip"):
        reward_sum(td)


def test_a_sum_stepped_outside_an_env_has_no_order_to_check_and_sums():
    """TorchRL's ``_step`` on a transform in no container (a parent that steps it itself)."""
    reward_sum = SumRewards(["reward", "penalty"], weights=[1.0, 2.0])
    td = TensorDict({"next": {"reward": torch.ones(1), "penalty": -0.25 * torch.ones(1)}})
    out = reward_sum._step(td, td["next"])
    assert out["reward"].item() == 0.5 and out[keys.TASK_REWARD].item() == 1.0
