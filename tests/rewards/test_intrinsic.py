"""``IntrinsicRewards`` by hand: ``from_env`` passes its seed and keys on, a group's shared
model steps (``share_steps``), ``update``'s count and losses, and ``RescoreRewards``' checks and
count of the batches it scored."""

import copy

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import RenameTransform, TransformedEnv

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.model_step import ModelStep
from tests.toy_env import ToyHandEnv

SMALL = dict(model_hidden=8, ensemble_size=2, model_batch_size=4)


def _rewards(seed: int = 0, **settings) -> IntrinsicRewards:
    return IntrinsicRewards(
        "r+rf+rsp", GentlenessConfig(**{**SMALL, **settings}), obs_dim=63, action_dim=20,
        feature_shapes={}, seed=seed,
    )  # fmt: skip


def _same_model(a: IntrinsicRewards, b: IntrinsicRewards) -> bool:
    x, y = a.losses["penalty"].model_params, b.losses["penalty"].model_params
    return all(torch.equal(x[k], y[k]) for k in x.keys(True, True))


def test_from_env_builds_the_seed_and_keys_it_is_given():
    env = TransformedEnv(
        ToyHandEnv(), RenameTransform(["observation", "touch"], ["state", "force"])
    )
    settings = GentlenessConfig(**SMALL)
    rewards = IntrinsicRewards.from_env(
        env, "r+rf+rsp", settings, obs_key="state", force_key="force", seed=3
    )
    assert (rewards.obs_key, rewards.force_key) == ("state", "force")
    assert rewards.losses["penalty"].model.obs_key == "state"
    assert rewards.transform[0].in_keys == ["force"]  # the impact penalty reads the force
    assert _same_model(rewards, _rewards(seed=3)) and not _same_model(rewards, _rewards(seed=0))
    # seed 0 by default, as the constructor's
    assert _same_model(IntrinsicRewards.from_env(ToyHandEnv(), "r+rf+rsp", settings), _rewards())


def test_update_counts_as_told_and_returns_each_models_loss_before_its_step():
    rewards = _rewards(rescore_surprise=False)
    batch = rewards.transform(ToyHandEnv().rollout(8))
    rewards.extend(batch)
    torch.manual_seed(1)
    sample = rewards.model_batches()["penalty"]
    twin = copy.deepcopy(rewards.losses["penalty"])  # the loss folds its batch into its norms
    expected = twin(sample.clone())["loss_penalty"].item()
    torch.manual_seed(1)
    metrics = rewards.update(7)
    assert list(metrics) == ["model_penalty"]
    assert metrics["model_penalty"] == pytest.approx(expected, rel=1e-5)
    assert rewards.num_updates == 7
    rewards.update()
    assert rewards.num_updates == 8


def _group(n: int = 2) -> tuple[list[IntrinsicRewards], dict[str, ModelStep]]:
    group = [_rewards(seed=s) for s in range(n)]
    steps = {"penalty": ModelStep([r.losses["penalty"] for r in group], 1e-2)}
    return group, steps


def test_a_seed_shares_its_groups_step_as_its_row_and_saves_that_row():
    group, steps = _group()
    for seat, rewards in enumerate(group):
        rewards.share_steps(steps, seat)
    assert group[1].steps == steps and group[1].steps["penalty"] is steps["penalty"]
    batch = rewards.transform(ToyHandEnv().rollout(8))
    for rewards in group:
        rewards.extend(batch)
    torch.manual_seed(0)
    steps["penalty"](torch.stack([r.model_batches()["penalty"] for r in group]))
    for seat, rewards in enumerate(group):
        saved = rewards.state_dict()["optimizers"]["penalty"]["state"]
        row = steps["penalty"].optimizer_state(seat)["state"]
        for index, moments in row.items():
            for name, value in moments.items():
                assert torch.equal(saved[index][name], value)
    first = group[0].state_dict()["optimizers"]["penalty"]["state"][0]["exp_avg"]
    assert not torch.equal(first, group[1].state_dict()["optimizers"]["penalty"]["state"][0][
        "exp_avg"])  # fmt: skip
    # a seed's saved state loads back into its own row; the other row keeps its new step
    saved, before = group[1].state_dict(), steps["penalty"].optimizer_state(0)
    steps["penalty"](torch.stack([r.model_batches()["penalty"] for r in group]))
    group[1].load_state_dict(saved)
    row1 = steps["penalty"].optimizer_state(1)["state"][0]["exp_avg"]
    row0 = steps["penalty"].optimizer_state(0)["state"][0]["exp_avg"]
    assert torch.equal(row1, saved["optimizers"]["penalty"]["state"][0]["exp_avg"])
    assert not torch.equal(row0, before["state"][0]["exp_avg"])
    with pytest.raises(
        RuntimeError,
        match=r"^IntrinsicRewards.update: these models step with other seeds' \(share_steps\); "
        r"the group's update steps them$",
    ):
        group[0].update()


def test_share_steps_refuses_other_models_and_another_seats_row():
    group, steps = _group()
    with pytest.raises(
        ValueError, match=r"^share_steps: steps for \['dynamics'\], models \['penalty'\]$"
    ):
        group[0].share_steps({"dynamics": steps["penalty"]}, 0)
    with pytest.raises(
        ValueError, match=r"^share_steps: row 0 of the 'penalty' step is not this model$"
    ):
        group[1].share_steps(steps, 0)
    assert group[1].steps["penalty"] is not steps["penalty"]  # its own step, still
    assert group[1].steps["penalty"].num_seeds == 1


def _scored_batch(rewards: IntrinsicRewards, steps: int = 1) -> TensorDict:
    batch = rewards.transform(ToyHandEnv().rollout(6))
    batch["steps_to_next_obs"] = torch.full((6, 1), steps)
    return batch


def test_rescore_rewards_score_each_batch_again_and_count_them():
    rewards = _rewards(reward_delay=0)
    rewards.step()  # the rewards on
    rescore = rewards.rescore_transform()
    assert rescore.reads == 0
    batch = _scored_batch(rewards)
    fresh = batch["next", keys.PENALTY_SURPRISE].clone()
    batch["next", keys.PENALTY_SURPRISE] = torch.full_like(fresh, 123.0)  # stale
    rescore(batch)
    torch.testing.assert_close(batch["next", keys.PENALTY_SURPRISE], fresh)
    rescore(batch)
    assert rescore.reads == 2


def test_rescore_rewards_refuse_a_batch_with_one_n_step_transition_in_full():
    rewards = _rewards()
    rescore = rewards.rescore_transform()
    batch = _scored_batch(rewards)
    batch["steps_to_next_obs"][3] = 2
    with pytest.raises(ValueError) as refused:
        rescore(batch)
    assert str(refused.value) == (
        "RescoreRewards scores 1-step transitions; this batch holds n-step ones "
        "(steps_to_next_obs up to 2), whose rewards are sums over steps it does not have: "
        "sample 1-step transitions, or use gentlerl's loop"
    )
    assert rescore.reads == 0


def test_the_settings_reach_the_impact_penalty_the_model_steps_the_multiplier_and_the_buffer():
    rewards = _rewards(
        lam=(3.0, 4.0), lr_model=0.05, model_buffer_size=7, tolerance=8.0, multiplier="pid",
        multiplier_gains=(0.5, 0.25, 0.125), multiplier_period=100, multiplier_integral_max=3.0,
        multiplier_base=0.0,
    )  # fmt: skip
    impact = rewards.transform[0]
    assert impact.lam == (3.0, 4.0) and impact.in_keys == [keys.TOUCH]
    assert impact.unit == 8.0 / 4.0  # the tolerance rule: T / lambda_2
    assert rewards.steps["penalty"].optimizer.param_groups[0]["lr"] == 0.05
    m = rewards.multiplier
    assert (m.tolerance, m.gains, m.period) == (8.0, (0.5, 0.25, 0.125), 100)
    assert (m.integral_max, m.base, m.weight) == (3.0, 0.0, 0.0)
    rewards.extend(rewards.transform(ToyHandEnv().rollout(10)))
    assert len(rewards.buffer) == 7  # the oldest 3 of 10 transitions overwritten
    paper = _rewards()
    assert paper.multiplier is None and paper.transform[0].unit == 1.0
    assert (paper.num_updates, paper.intrinsic_on, paper.device) == (0, False, torch.device("cpu"))
