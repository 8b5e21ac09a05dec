"""The drop-in API for other TorchRL agents: ``IntrinsicRewards.from_env``, ``SumRewards``,
``RescoreRewards`` (``rescore_transform``), the self-counting schedule and the stale-model guard."""

import multiprocessing
import re

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import RewardSum, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.functional import gaussian_nll, mixture_moments, penalty_surprise
from gentlerl.rewards import IntrinsicRewards, RescoreRewards, SumRewards
from tests.helpers import pressing_rollout
from tests.toy_env import ToyHandEnv

SMALL = dict(model_hidden=16, ensemble_size=3, model_batch_size=8)
COMPONENTS = [keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE]


def small_rewards(env=None, **settings) -> IntrinsicRewards:
    settings = {**SMALL, **settings}
    return IntrinsicRewards.from_env(env or ToyHandEnv(), "r+rf+rsp", GentlenessConfig(**settings))


def summed_env(rewards: IntrinsicRewards) -> tuple[TransformedEnv, SumRewards]:
    reward_sum = SumRewards(rewards.reward_keys)
    env = TransformedEnv(ToyHandEnv(), rewards.transform.clone())  # shares models and gate
    env.append_transform(RewardSum())
    env.append_transform(reward_sum)
    return env, reward_sum


def test_from_env_reads_every_size_from_the_specs():
    rewards = small_rewards()
    (loss,) = rewards.losses.values()
    model = loss.model
    assert (model.obs_dim, model.action_dim) == (63, 20)
    assert rewards.reward_keys == COMPONENTS
    dyn = IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rs", GentlenessConfig(**SMALL))
    shapes = dyn.losses["dynamics"].model.feature_shapes
    assert shapes == {keys.JOINT_POS: (24,), keys.JOINT_VEL: (24,), keys.TOUCH: (5, 3)}


def test_from_env_names_a_missing_key_and_the_keys_there():
    with pytest.raises(KeyError, match=r"force_key='force'.*'touch'"):
        IntrinsicRewards.from_env(ToyHandEnv(), "r+rf", force_key="force")
    with pytest.raises(ValueError, match=r"n_sites >= 1, n_channels >= 1.*\(63,\)"):
        IntrinsicRewards.from_env(ToyHandEnv(), "r+rf", force_key=keys.OBSERVATION)


def test_from_env_builds_on_the_device_it_is_given():
    rewards = IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", device="cpu")
    (loss,) = rewards.losses.values()
    assert {p.device.type for p in loss.parameters()} == {"cpu"}
    with pytest.raises(RuntimeError, match="bogus"):
        IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", device="bogus")


def test_sum_rewards_is_the_weighted_sum_and_keeps_the_task_reward():
    td = TensorDict({"next": {"reward": torch.tensor([1.0]), "penalty": torch.tensor([-0.5])}})
    out = SumRewards(["reward", "penalty"], weights=[2.0, 3.0])(td)
    assert out["next", "reward"].item() == 2.0 * 1.0 + 3.0 * -0.5
    assert out["next", keys.TASK_REWARD].item() == 1.0
    # applied again (a component recomputed at sampling): the sum of the parts, not of the sum
    out["next", "penalty"] = torch.tensor([-1.0])
    assert SumRewards(["reward", "penalty"])(out)["next", "reward"].item() == 1.0 - 1.0


def test_sum_rewards_refuses_bad_arguments():
    with pytest.raises(ValueError, match="distinct"):
        SumRewards(["reward", "reward"])
    with pytest.raises(ValueError, match="2 weights for 3 keys"):
        SumRewards(COMPONENTS, weights=[1.0, 1.0])
    td = TensorDict({"next": {"reward": torch.ones(1)}})
    with pytest.raises(KeyError, match="'penalty'"):
        SumRewards(["reward", "penalty"])(td)


def test_the_summed_env_has_one_reward_and_valid_specs():
    env, _ = summed_env(small_rewards(reward_delay=0))
    check_env_specs(env)
    assert env.reward_key == keys.REWARD and env.reward_keys == [keys.REWARD]
    rollout = pressing_rollout(env)
    n = rollout["next"]
    parts = n[keys.TASK_REWARD] + n[keys.PENALTY] + n[keys.PENALTY_SURPRISE]
    torch.testing.assert_close(n[keys.REWARD], parts)
    assert (n[keys.PENALTY][6:] < 0).all()
    # RewardSum came first: episode_reward is the task's return, not the summed one
    torch.testing.assert_close(n["episode_reward"], n[keys.TASK_REWARD].cumsum(0))
    assert env.reset()[keys.PENALTY].item() == 0  # the components are observations after a reset


def test_a_reward_sum_after_the_sum_is_refused():
    rewards = small_rewards()
    env = TransformedEnv(ToyHandEnv(), rewards.transform.clone())
    env.append_transform(SumRewards(rewards.reward_keys))
    env.append_transform(RewardSum())
    with pytest.raises(ValueError, match="put RewardSum before SumRewards"):
        env.rollout(2)


def _contact_batch(rewards: IntrinsicRewards):
    env, reward_sum = summed_env(rewards)
    return reward_sum, pressing_rollout(env)


def test_rescore_rewards_score_a_sample_with_the_current_target_model():
    rewards = small_rewards(reward_delay=1, penalty_target_period=1)
    reward_sum, batch = _contact_batch(rewards)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(100), batch_size=12)
    rb.append_transform(rewards.rescore_transform(reward_sum))
    rb.extend(batch)
    rewards.extend(batch)
    assert (rb[:]["next", keys.PENALTY_SURPRISE] == 0).all()  # the gate is still closed
    for _ in range(3):  # the gate opens, the target copies the trained model each update
        rewards.update()
    sample = rb[:]
    fresh = sample["next", keys.PENALTY_SURPRISE]
    # eq. 8 with the target ensemble's mixture, computed here by hand
    (loss,) = rewards.losses.values()
    with torch.no_grad(), loss.target_model_params.to_module(loss.model):
        mean, var = loss.model.predict(sample)
    mu, sigma2 = mixture_moments(mean, var, dim=0)
    penalty = sample["next", keys.PENALTY]
    nll = gaussian_nll(penalty, mu, sigma2)
    expected = torch.where(penalty < 0, penalty_surprise(penalty, nll, 2.0, 2.0), 0.0)
    torch.testing.assert_close(fresh, expected)
    assert (fresh[penalty < 0] != 0).all() and (fresh[penalty == 0] == 0).all()
    # the same values as gentlerl's own transform on that batch now, and the sum redone
    now = rewards.transform(batch.clone())["next", keys.PENALTY_SURPRISE]
    torch.testing.assert_close(fresh, now)
    n = sample["next"]
    torch.testing.assert_close(n[keys.REWARD], n[keys.TASK_REWARD] + n[keys.PENALTY] + fresh)
    stored = rb.storage[:]["next", keys.PENALTY_SURPRISE]
    assert (stored == 0).all()  # the buffer keeps what was collected; the sample is fresh


def test_fresh_rewards_refuse_n_step_transitions():
    rewards = small_rewards()
    _, batch = _contact_batch(rewards)
    batch["steps_to_next_obs"] = torch.full((12, 1), 3)
    with pytest.raises(ValueError, match="1-step transitions.*up to 3"):
        RescoreRewards(rewards.gated_transforms)(batch)


def test_rescore_surprise_never_used_is_an_error_once_the_rewards_are_on():
    rewards = small_rewards(reward_delay=2)
    _, batch = _contact_batch(rewards)
    rewards.extend(batch)
    for _ in range(3):  # the gate opens after the second; the first update with it on may
        rewards.update()  # come before its batch is sampled
    with pytest.raises(RuntimeError, match="rescore_transform"):
        rewards.update()
    quiet = small_rewards(reward_delay=2, rescore_surprise=False)
    quiet.extend(batch)
    for _ in range(3):
        quiet.update()
    assert quiet.intrinsic_on


def test_update_counts_its_own_steps_as_an_explicit_count_does():
    counted, explicit = small_rewards(reward_delay=3), small_rewards(reward_delay=3)
    _, batch = _contact_batch(counted)
    for stack in (counted, explicit):
        stack.extend(batch)
        stack.rescore_transform()(batch.clone())
    torch.manual_seed(0)
    for _ in range(2):
        counted.update()
    assert counted.num_updates == 2 and not counted.intrinsic_on
    counted.update()  # the third update: the delay of 3 updates has passed
    torch.manual_seed(0)
    for count in (1, 2, 3):
        explicit.update(count)
    assert counted.intrinsic_on and explicit.intrinsic_on and counted.num_updates == 3
    (a,), (b,) = counted.losses.values(), explicit.losses.values()
    for x, y in zip(a.parameters(), b.parameters(), strict=True):
        torch.testing.assert_close(x, y)
    state = counted.state_dict()
    fresh = small_rewards(reward_delay=3)
    fresh.load_state_dict(state)
    assert fresh.num_updates == 3


def _score_in_child(transform, batch, queue) -> None:
    try:
        transform(batch)
        queue.put("ran")
    except RuntimeError as error:
        queue.put(str(error))


def test_a_model_reward_in_another_process_is_an_error():
    rewards = small_rewards(reward_delay=0)
    rewards.step()
    _, batch = _contact_batch(rewards)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_score_in_child, args=(rewards.transform, batch, queue))
    child.start()
    message = queue.get(timeout=60)
    child.join(timeout=60)
    assert "its model trains in process" in message and "rescore_transform" in message
    rewards.transform(batch)  # in its own process it still runs


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"lam_prime": (float("nan"), 2.0)}, r"gentleness.lam_prime\[0\]=nan must be a finite"),
        ({"reward_delay": -1}, "gentleness.reward_delay=-1 must be >= 0"),
        ({"model_batch_size": 0}, r"gentleness.model_batch_size=0 must be in \[1, 65536\]"),
        ({"lam": (0.0, 2.0)}, r"gentleness.lam=\(0.0, 2.0\) must be \[lambda_1 > 0"),
    ],
)
def test_the_drop_in_checks_its_settings_as_gentlerl_train_does(settings, message):
    """The findings: these settings were accepted by IntrinsicRewards (the CLI refused them)."""
    with pytest.raises(ValueError, match=f"invalid GentlenessConfig: {message}"):
        small_rewards(**settings)


def test_sum_rewards_refuses_a_non_finite_weight():
    with pytest.raises(
        ValueError, match=r"SumRewards: weights must be finite numbers, got \[nan\]"
    ):
        SumRewards(["reward"], weights=[float("nan")])


@pytest.mark.parametrize(
    ("shape", "dtype", "message"),
    [
        ((0, 3), torch.float32, r"must be \[n_sites >= 1, n_channels >= 1\], got \(0, 3\)"),
        ((5, 3, 2), torch.float32, r"must be \[n_sites >= 1, n_channels >= 1\], got \(5, 3, 2\)"),
        ((5, 3), torch.bool, "must be float32, got torch.bool"),
        ((5, 3), torch.float64, r"must be float32, got torch.float64 \(torchrl's DoubleToFloat"),
    ],
)
def test_from_env_refuses_a_force_that_is_no_force(shape, dtype, message):
    from torchrl.data import Unbounded

    env = ToyHandEnv()
    spec = env.observation_spec.clone()
    spec["force"] = Unbounded(shape=shape, dtype=dtype)
    env.observation_spec = spec
    with pytest.raises(ValueError, match=f"IntrinsicRewards.from_env: 'force' {message}"):
        IntrinsicRewards.from_env(env, "r+rf+rsp", force_key="force")


def test_update_before_extend_and_empty_batches_are_named():
    rewards = small_rewards()
    message = (
        "IntrinsicRewards.update() before any extend(): the models have no transition to learn "
        "from (extend() each collected, transformed batch first)"
    )
    with pytest.raises(RuntimeError, match=f"^{re.escape(message)}$"):
        rewards.update()
    batch = ToyHandEnv().rollout(3)
    with pytest.raises(ValueError, match=r"the reward transforms got an empty batch \(0,\)"):
        rewards.transform(batch[:0])
    with pytest.raises(ValueError, match=r"IntrinsicRewards.extend: the batch is empty \(0,\)"):
        rewards.extend(rewards.transform(batch)[:0])


def test_from_env_refuses_an_image_observation_and_a_meta_device():
    from torchrl.data import Unbounded

    env = ToyHandEnv()
    spec = env.observation_spec.clone()
    spec["pixels"] = Unbounded(shape=(3, 8, 8))
    env.observation_spec = spec
    with pytest.raises(ValueError, match=r"'pixels' must be a flat float vector \[obs_dim\], got"):
        IntrinsicRewards.from_env(env, "r+rf+rsp", obs_key="pixels")
    with pytest.raises(ValueError, match="device must be cpu or cuda, got meta"):
        IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", device="meta")


def test_a_deep_copy_of_fresh_rewards_scores_with_the_trained_model():
    """The finding: a deep copy or pickle of RescoreRewards had its own model whose gate never
    opened; a deep copy now shares the model and gate, an unpickled one refuses to run."""
    import copy
    import pickle

    rewards = small_rewards(reward_delay=1)
    _, reward_sum = summed_env(rewards)
    fresh = rewards.rescore_transform(reward_sum)
    copied, unpickled = copy.deepcopy(fresh), pickle.loads(pickle.dumps(fresh))
    for mine, theirs in zip(copied.rewards, rewards.gated_transforms, strict=True):
        assert mine.model is theirs.model and mine.active is theirs.active
    batch = rewards.transform(ToyHandEnv().rollout(5))
    with pytest.raises(RuntimeError, match="was unpickled: its model is a copy"):
        unpickled(batch.clone())
