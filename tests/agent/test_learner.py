"""Learner: one grouped optimiser step per update, target copies on schedule, state round trip."""

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
    assert b.target_updater.counter == a.target_updater.counter == 1
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
