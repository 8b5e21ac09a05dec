"""``IntrinsicRewards`` by hand: ``from_env`` passes its seed and keys on, a group's shared
model steps (``share_steps``), ``update``'s count and losses, and ``RescoreRewards``' checks and
count of the batches it scored."""

import copy
import warnings

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import RenameTransform, TransformedEnv

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.rewards.model_step import ModelStep
from tests.helpers import pressing_rollout
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


def _trained(**settings) -> IntrinsicRewards:
    rewards = _rewards(reward_delay=2, rescore_surprise=False, penalty_target_period=3, **settings)
    rewards.extend(rewards.transform(ToyHandEnv().rollout(12)))
    for _ in range(2):
        rewards.update()
    rewards.transform(pressing_rollout(ToyHandEnv()))  # contact: folds the curiosity scale
    return rewards


def test_a_saved_state_loads_into_a_fresh_object_entry_by_entry():
    settings = dict(curiosity_norm=True, tolerance=4.0, multiplier="pid")
    rewards = _trained(**settings)
    rewards.multiplier.observe([8.0])
    state = rewards.state_dict()
    assert state["active"] is True and state["num_updates"] == 2
    assert state["target_counters"] == {"penalty": 2}
    assert state["curiosity_scales"] == [list(rewards.transform[1].curiosity_scale)]
    assert state["curiosity_scales"][0][1] >= 1
    assert state["multiplier"] == rewards.multiplier.state_dict()
    fresh = _rewards(reward_delay=2, rescore_surprise=False, penalty_target_period=3, **settings)
    fresh.load_state_dict(state)
    again = fresh.state_dict()
    assert again["active"] is True and again["num_updates"] == 2
    assert again["target_counters"] == state["target_counters"]
    assert again["curiosity_scales"] == state["curiosity_scales"]
    assert again["multiplier"] == state["multiplier"]
    assert _same_model(fresh, rewards)
    for index, moments in state["optimizers"]["penalty"]["state"].items():
        for name, value in moments.items():
            assert torch.equal(again["optimizers"]["penalty"]["state"][index][name], value)
    # the next target copy comes after the same number of steps in both
    fresh.step(), rewards.step()
    target = rewards.losses["penalty"].target_model_params
    other = fresh.losses["penalty"].target_model_params
    assert all(torch.equal(target[k], other[k]) for k in target.keys(True, True))


def test_an_older_checkpoint_without_the_newer_entries_loads_with_their_defaults():
    state = _trained().state_dict()
    for name in ("num_updates", "curiosity_scales", "multiplier"):
        del state[name]
    fresh = _rewards(curiosity_norm=True, tolerance=4.0, multiplier="pid")
    fresh.load_state_dict(state)
    assert fresh.num_updates == 0 and fresh.transform[1].curiosity_scale == (0.0, 0)
    assert (
        fresh.multiplier.state_dict()
        == _rewards(tolerance=4.0, multiplier="pid").multiplier.state_dict()
    )
    assert fresh.intrinsic_on  # "active" is read


def test_extend_keeps_flat_transitions_without_the_touch_grid_and_the_collectors_entries():
    rewards = _rewards()
    batch = rewards.transform(ToyHandEnv().rollout(6)).reshape(2, 3)
    batch[keys.TOUCH_GRID] = torch.zeros(2, 3, 5, 3, 4, 4)
    batch["next", keys.TOUCH_GRID] = torch.zeros(2, 3, 5, 3, 4, 4)
    batch["collector", "traj_ids"] = torch.zeros(2, 3, dtype=torch.int64)
    rewards.extend(batch)
    stored = rewards.buffer[:]
    assert stored.batch_size == (6,)
    assert keys.TOUCH_GRID not in stored.keys() and "collector" not in stored.keys()
    assert ("next", keys.TOUCH_GRID) not in stored.keys(True)
    torch.testing.assert_close(stored[keys.OBSERVATION], batch[keys.OBSERVATION].reshape(6, -1))
    no_model = IntrinsicRewards(
        "r+rf", GentlenessConfig(), obs_dim=63, action_dim=20, feature_shapes={}
    )
    assert no_model.buffer is None and no_model.losses == {}
    no_model.extend(batch)  # nothing to keep: no model learns
    assert no_model.model_batches() == {} and no_model.update() == {}


def test_an_ensembles_batch_is_one_bootstrap_batch_per_member():
    rewards = _rewards(ensemble_size=3, model_batch_size=5, rescore_surprise=False)
    rewards.extend(rewards.transform(ToyHandEnv().rollout(4)))
    (batch,) = rewards.model_batches().values()
    assert batch.batch_size == (3, 5)


def test_the_rewards_switch_on_at_the_reward_delay_and_the_count_is_kept():
    rewards = _rewards(reward_delay=3)
    rewards.step(2)
    assert not rewards.intrinsic_on and not rewards.transform[1].active
    rewards.step()
    assert rewards.num_updates == 3 and rewards.intrinsic_on
    rewards.step(1)  # an explicit count wins, and may switch them off again
    assert rewards.num_updates == 1 and not rewards.intrinsic_on


def test_without_rescore_surprise_windows_are_left_as_they_are():
    rewards = _rewards(rescore_surprise=False)
    assert rewards.rescored == [] and rewards.window_keys == []
    batch = TensorDict({"next": {keys.PENALTY_SURPRISE: torch.ones(3, 1)}}, [3])
    assert rewards.rescore_windows(batch, 0.9) == {}
    assert (batch["next", keys.PENALTY_SURPRISE] == 1).all()
    paper = _rewards()
    assert paper.window_keys == [keys.OBSERVATION, keys.ACTION, ("next", keys.PENALTY)]


def test_the_models_are_seeded_0_and_step_eagerly_by_default(monkeypatch):
    from gentlerl.objectives import launch as compiling

    settings = GentlenessConfig(**SMALL)
    default = IntrinsicRewards("r+rf+rsp", settings, obs_dim=63, action_dim=20, feature_shapes={})
    assert _same_model(default, _rewards(seed=0))
    monkeypatch.setattr(compiling, "compile_unavailable", lambda: "no C++ compiler (test)")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # eager: no compile to fall back from
        eager = IntrinsicRewards("r+rf+rsp", settings, obs_dim=63, action_dim=20, feature_shapes={})
        assert eager.steps
    with pytest.warns(UserWarning, match="no C.. compiler \\(test\\); the reward models runs"):
        assert IntrinsicRewards(  # the steps are built (compiled) on first use
            "r+rf+rsp", settings, obs_dim=63, action_dim=20, feature_shapes={}, compile=True
        ).steps
