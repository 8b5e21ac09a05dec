"""Learner: one grouped optimiser step per update, target copies on schedule, state round trip;
S seeds as one step equal S learners of their own."""

import dataclasses

import pytest
import torch
from tensordict import TensorDict

from gentlerl.agent.learner import Learner, TrainingState
from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss


def _learner(period=3, lr_actor=1e-3, lr_critic=1e-2):
    torch.manual_seed(0)
    critic = make_critic(3, 1, 2, (16,), 11, v_min=-5.0, v_max=5.0)
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=["reward", "penalty"])
    return Learner(loss, lr_actor=lr_actor, lr_critic=lr_critic, target_update_period=period)


def _batch(n=16):
    nxt = {"observation": torch.randn(n, 3), "reward": torch.ones(n, 1),
           "penalty": -torch.ones(n, 1), "terminated": torch.zeros(n, 1, dtype=torch.bool)}  # fmt: skip
    return TensorDict(
        {"observation": torch.randn(n, 3), "action": torch.rand(n, 1), "next": nxt}, [n]
    )


def test_one_optimiser_two_step_sizes():
    learner = _learner()
    assert [g["lr"] for g in learner.optimizer.param_groups] == [1e-3, 1e-2]


def test_update_steps_both_networks_and_copies_targets_every_period():
    learner = _learner(period=3)
    loss = learner.loss
    actor0 = loss.actor_network_params.clone()
    target0 = loss.target_value_network_params.clone()
    out = learner.update(_batch())
    assert {"loss_value", "loss_actor"} <= set(out.keys()) and not out["loss_value"].requires_grad
    assert not (loss.actor_network_params == actor0).all()
    learner.update(_batch())
    assert (loss.target_value_network_params == target0).all()  # 2 updates: no copy yet
    learner.update(_batch())  # the 3rd update copies
    assert (loss.target_value_network_params == loss.value_network_params.data).all()


def test_state_round_trip():
    a, b = _learner(), _learner()
    a.update(_batch())
    b.restore(TrainingState(**dataclasses.asdict(a.state)))
    assert b.target_counter == a.target_counter == 1
    assert (b.loss.actor_network_params == a.loss.actor_network_params).all()
    sa, sb = a.optimizer.state_dict()["state"], b.optimizer.state_dict()["state"]
    assert all(torch.equal(sa[k]["exp_avg"], sb[k]["exp_avg"]) for k in sa)


def test_bad_period():
    with pytest.raises(ValueError, match="target_update_period must be >= 1, got 0"):
        _learner(period=0)


def test_a_separate_policy_acts_with_the_weights_of_the_last_sync():
    torch.manual_seed(0)
    critic = make_critic(3, 1, 2, (16,), 11, v_min=-5.0, v_max=5.0)
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=["reward", "penalty"])
    learner = Learner(
        loss, lr_actor=1e-2, lr_critic=1e-2, target_update_period=3, separate_policy=True
    )
    obs = TensorDict({"observation": torch.randn(8, 3)}, [8])
    before = learner.policy(obs.clone())["action"]
    learner.update(_batch())
    torch.testing.assert_close(learner.policy(obs.clone())["action"], before)  # not yet synced
    learner.sync_policy()
    trained = learner.actor(obs.clone())["action"]
    assert not torch.equal(trained, before)
    torch.testing.assert_close(learner.policy(obs.clone())["action"], trained)


def test_a_cpu_learner_acts_with_its_own_actor():
    learner = _learner()
    assert learner.policy is learner.actor


KEYS = ["reward", "penalty"]


def _loss(seed):
    torch.manual_seed(seed)
    critic = make_critic(3, 1, 2, (16, 8), 11, v_min=-5.0, v_max=[5.0, 0.0])
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=KEYS)
    loss.make_value_estimator(gamma=0.9)
    return loss


def _seeded_batch(n, seed):
    g = torch.Generator().manual_seed(seed)
    nxt = {
        "observation": torch.randn(n, 3, generator=g),
        "reward": torch.rand(n, 1, generator=g),
        "penalty": -torch.rand(n, 1, generator=g),
        "terminated": torch.rand(n, 1, generator=g) < 0.2,
    }
    obs, act = torch.randn(n, 3, generator=g), torch.rand(n, 1, generator=g) * 2 - 1
    return TensorDict({"observation": obs, "action": act, "next": nxt}, [n])


OPTIONS = dict(lr_actor=1e-3, lr_critic=1e-2, target_update_period=2)


def test_three_seeds_in_one_learner_equal_three_lone_learners_over_50_updates():
    """The seed axis is exact: 50 updates (25 target copies) of 3 seeds as one step give each
    seed's losses, priorities, parameters and Adam moments of a learner of its own, to 1e-5."""
    seeds = [0, 1, 2]
    alone = [Learner(_loss(s), **OPTIONS) for s in seeds]
    group = Learner([_loss(s) for s in seeds], **OPTIONS)
    for step in range(50):
        rows = [_seeded_batch(32, 10 * step + s) for s in seeds]
        stacked = torch.stack([r.clone() for r in rows])
        out = group.update(stacked)
        for s, learner in enumerate(alone):
            ref = learner.update(rows[s])
            for key in ("loss_value", "loss_actor", "value_reward", "value_penalty"):
                torch.testing.assert_close(out[key][s], ref[key], rtol=1e-5, atol=1e-5)
            torch.testing.assert_close(
                stacked["td_error"][s], rows[s]["td_error"], rtol=1e-5, atol=1e-5
            )
    for s, learner in enumerate(alone):
        got, want = group.losses[s].network_params(), learner.loss.network_params()
        for key, value in want.items(True, True):
            torch.testing.assert_close(got[key], value, rtol=1e-5, atol=1e-5)
        mine, ref = group.state_of(s).optimizer["state"], learner.state.optimizer["state"]
        for index, moments in ref.items():
            torch.testing.assert_close(
                mine[index]["exp_avg"], moments["exp_avg"], rtol=1e-4, atol=1e-6
            )


def test_seeds_stay_independent():
    """A seed's parameters do not move when only another seed's batch changes."""
    a = Learner([_loss(0), _loss(1)], **OPTIONS)
    b = Learner([_loss(0), _loss(1)], **OPTIONS)
    batch = torch.stack([_seeded_batch(16, 0), _seeded_batch(16, 1)])
    other = batch.clone()
    other[1] = _seeded_batch(16, 99)
    for _ in range(3):
        a.update(batch.clone())
        b.update(other.clone())
    moved = []
    for key, value in a.params["value"].items(True, True):
        torch.testing.assert_close(value[0], b.params["value"][key][0], rtol=0, atol=0)
        moved.append(not torch.equal(value[1], b.params["value"][key][1]))
    assert all(moved)


def test_several_seeds_refuse_a_batch_without_the_seed_axis_and_one_seeds_views():
    learner = Learner([_loss(0), _loss(1)], **OPTIONS)
    with pytest.raises(ValueError, match=r"shaped \[num_seeds=2, B\], got \(16,\)"):
        learner.update(_seeded_batch(16, 0))
    with pytest.raises(ValueError, match="Learner.policy is one seed's; this learner has 2"):
        _ = learner.policy
    with pytest.raises(IndexError, match="seed index 2 out of range for 2 seeds"):
        learner.state_of(2)
    with pytest.raises(ValueError, match="needs a CUDA learner, this one is on cpu"):
        Learner([_loss(0)], cudagraphs=True, **OPTIONS)


def test_each_seed_acts_with_its_row_and_its_saved_state_resumes_alone():
    """Each seed's own actor acts with its row after the group's updates (no copy), and its
    :meth:`state_of` restored into a learner of its own steps as a lone learner does."""
    seeds = [0, 1]
    alone = [Learner(_loss(s), **OPTIONS) for s in seeds]
    group = Learner([_loss(s) for s in seeds], **OPTIONS)
    obs = TensorDict({"observation": torch.randn(4, 3)}, [4])
    for step in range(3):
        rows = [_seeded_batch(16, 10 * step + s) for s in seeds]
        group.update(torch.stack([r.clone() for r in rows]))
        for learner, row in zip(alone, rows, strict=True):
            learner.update(row)
    for s, ref in enumerate(alone):
        act = group.policy_of(s)(obs.clone())["action"]
        torch.testing.assert_close(act, ref.policy(obs.clone())["action"], rtol=1e-5, atol=1e-6)
        resumed = Learner(_loss(7), **OPTIONS)
        resumed.restore(group.state_of(s))
        assert resumed.target_counter == ref.target_counter == 1
        row = _seeded_batch(16, 50 + s)
        resumed.update(row.clone())
        ref.update(row)
        for key, value in ref.loss.network_params().items(True, True):
            got = resumed.loss.network_params()[key]
            torch.testing.assert_close(got, value, rtol=1e-5, atol=1e-6)


def test_the_deprecated_seed_batched_learner_warns_and_is_a_learner():
    from gentlerl.agent import SeedBatchedLearner

    with pytest.warns(DeprecationWarning, match="SeedBatchedLearner is deprecated since 0.2.0"):
        learner = SeedBatchedLearner([_loss(0), _loss(1)], share=True, **OPTIONS)
    assert isinstance(learner, Learner) and learner.num_seeds == 2


def test_bad_learning_rates_are_refused_in_one_line():
    for lr in (float("nan"), float("inf"), 0.0, -1.0, True, "1e-3"):
        with pytest.raises(ValueError, match=f"lr_actor must be a finite number > 0, got {lr!r}"):
            Learner(_loss(0), lr_actor=lr, lr_critic=1e-3, target_update_period=2)
    with pytest.raises(ValueError, match="target_update_period must be >= 1, got True"):
        Learner(_loss(0), lr_actor=1e-3, lr_critic=1e-3, target_update_period=True)
    loss = _loss(0)  # the finding: the same loss twice trained one module as two seeds
    with pytest.raises(
        ValueError, match="seeds 0 and 1 hold the same tensor .*one loss passed twice"
    ):
        Learner([loss, loss], lr_actor=1e-3, lr_critic=1e-3, target_update_period=2)


def test_after_each_target_copy_every_seeds_targets_equal_its_online_networks_entry_by_entry():
    """The invariant TorchRL's HardUpdate broke for the reward models (it copies only what
    takes a gradient): after every copy, every entry of every seed's target actor and critics,
    parameters and buffers alike, equals the online one, in the stack and in the seed's loss."""
    learner = Learner([_loss(0), _loss(1)], **OPTIONS)  # a copy every 2 updates
    for step in range(6):
        learner.update(torch.stack([_seeded_batch(16, 10 * step + s) for s in (0, 1)]))
        if learner.target_counter:
            continue
        for online, target in (("actor", "target_actor"), ("value", "target_value")):
            want, got = learner.params[online], learner.params[target]
            assert set(want.keys(True, True)) == set(got.keys(True, True))
            for key, value in want.items(True, True):
                assert torch.equal(got[key], value), (step, target, key)
        for loss in learner.losses:
            for key, value in loss.value_network_params.items(True, True):
                assert torch.equal(loss.target_value_network_params[key], value)
