"""MultiHeadD4PGLoss: the head weights w_k and the importance weights in the actor loss, and the
priorities written into the batch's own tensor."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss

OBS, ACT = 3, 1


def _loss():
    torch.manual_seed(0)
    actor = make_actor(OBS, ACT, hidden=(16,))
    critic = make_critic(OBS, ACT, 2, (16,), 11, v_min=-5.0, v_max=5.0)
    loss = MultiHeadD4PGLoss(actor, critic, reward_keys=["reward", "penalty"])
    loss.make_value_estimator(gamma=0.9)
    return loss


def _batch(n=8):
    # Two kinds of states, so that the samples' actor objectives differ.
    obs = torch.cat([torch.ones(n // 2, OBS), -3 * torch.ones(n - n // 2, OBS)])
    return TensorDict(
        {
            "observation": obs,
            "action": torch.zeros(n, ACT),
            "next": {
                "observation": obs.clone(),
                "reward": torch.ones(n, 1),
                "penalty": -torch.ones(n, 1),
                "terminated": torch.zeros(n, 1, dtype=torch.bool),
            },
        },
        [n],
    )


def test_the_actor_loss_weights_each_heads_value_by_its_head_weight():
    # L_actor = -E[sum_k w_k E[Z^k(s, pi(s))]]: with w = [1, 3], -(Q_reward + 3 Q_penalty).
    loss = _loss()
    td = _batch()
    loss.set_head_weight("penalty", 3.0)
    assert loss.head_weights.tolist() == [1.0, 3.0]
    actor, info = loss.loss_actor(td.clone())
    torch.testing.assert_close(actor, -(info["value"][0] + 3.0 * info["value"][1]))
    torch.testing.assert_close(loss(td)["loss_actor"], actor)
    with pytest.raises(KeyError, match="'bogus' is not one of the heads"):
        loss.set_head_weight("bogus", 2.0)


def test_priority_weights_weight_the_actor_loss_too():
    # TorchRL's sum(w * l) / sum(w): samples of weight 0 drop out of the actor loss as well.
    loss = _loss()
    td = _batch()
    first_half = loss.loss_actor(td[:4].clone())[0]
    assert not torch.allclose(first_half, loss.loss_actor(td.clone())[0])  # the halves differ
    td["priority_weight"] = torch.tensor([1.0] * 4 + [0.0] * 4)
    torch.testing.assert_close(loss.loss_actor(td)[0], first_half)


@pytest.mark.parametrize("call", ["forward", "loss_value"])
def test_priorities_are_written_into_the_batchs_own_td_error_tensor(call):
    # In place: a captured (CUDA-graph) step or a replay view holding the tensor sees them.
    loss = _loss()
    td = _batch()
    held = torch.zeros(8)
    td["td_error"] = held
    getattr(loss, call)(td)
    assert td["td_error"] is held or td["td_error"].data_ptr() == held.data_ptr()
    assert (held > 0).all()


def test_head_weights_and_episodic_flags_are_not_in_the_state_dict():
    # Both are set from the config and the run state when a run starts or resumes (the PID
    # multiplier's w_k), so a checkpoint of the loss holds the networks only.
    loss = _loss()
    loss.set_head_weight("penalty", 3.0)
    keys = set(loss.state_dict())
    assert not {"head_weights", "episodic"} & keys
    assert any(k.startswith("value_network_params") for k in keys)
