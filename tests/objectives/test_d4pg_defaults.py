"""MultiHeadD4PGLoss: its defaults, batch shapes, the parameters ``losses`` is given, nested
reward keys and TorchRL's loss mask; each test kills mutants that survived the rest of
``tests/objectives`` (``benchmarks/mutation.py objectives``; named in each test)."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss

OBS, ACT = 3, 2


def _loss(keys=("reward", "penalty"), **kwargs):
    torch.manual_seed(0)
    actor = make_actor(OBS, ACT, hidden=(8,))
    critic = make_critic(OBS, ACT, len(keys), (8,), 11, v_min=-5.0, v_max=5.0)
    loss = MultiHeadD4PGLoss(actor, critic, reward_keys=list(keys), **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss


def _batch(*shape):
    gen = torch.Generator().manual_seed(1)
    return TensorDict(
        {
            "observation": torch.randn(*shape, OBS, generator=gen),
            "action": torch.rand(*shape, ACT, generator=gen) * 2 - 1,
            "next": {
                "observation": torch.randn(*shape, OBS, generator=gen),
                "reward": torch.randn(*shape, 1, generator=gen),
                "penalty": -torch.rand(*shape, 1, generator=gen),
                "terminated": torch.zeros(*shape, 1, dtype=torch.bool),
            },
        },
        list(shape),
    )


def test_no_reward_key_is_refused_in_its_own_words():  # __init__ _10
    with pytest.raises(ValueError, match=r"^reward_keys must name at least one reward component"):
        MultiHeadD4PGLoss(make_actor(OBS, ACT, hidden=(8,)), make_critic(OBS, ACT, 1, (8,), 11),
                          reward_keys=[])  # fmt: skip


def test_the_default_noise_clip_bounds_the_target_actions_noise_at_half():  # __init__ _2
    # policy_noise 100: almost every draw hits the clip, so the noisy action moves by exactly
    # 0.5 (the default clip) unless [-1, 1] stops it first; never by more.
    loss = _loss(policy_noise=100.0)
    seen = []
    critic = loss._critic
    loss._critic = lambda td, params: (seen.append(td.get("action").clone()), critic(td, params))[1]
    batch = _batch(64)
    loss.target_distribution(batch)
    with loss.target_actor_network_params.to_module(loss.actor_network):
        clean = loss.actor_network(batch["next"].select("observation").clone())["action"]
    moved = (seen[0] - clean).abs()
    assert moved.max().item() <= 0.5 + 1e-6
    assert moved.max().item() == pytest.approx(0.5, abs=1e-6)


def test_the_default_keeps_a_target_actor_of_its_own():  # __init__ _3, _55, _58
    # delay_actor=True by default: moving the online actor leaves its target copy where it was.
    loss = _loss()
    before = loss.target_actor_network_params.clone()
    with torch.no_grad():
        for p in loss.actor_network_params.values(True, True):
            p.add_(1.0)
    for key, value in before.items(True, True):
        torch.testing.assert_close(loss.target_actor_network_params[key], value)
        assert not torch.equal(loss.actor_network_params[key], value)


def test_a_two_dim_batch_gives_the_flat_batchs_losses_and_priorities():  # _actor_terms _32,
    # _value_terms _39: the heads' dim is the last one, whatever the batch's shape.
    loss = _loss()
    grid, flat = _batch(2, 3), _batch(2, 3).reshape(6)
    out, priority = loss.losses(grid, loss.network_params())
    out_flat, priority_flat = loss.losses(flat, loss.network_params())
    assert priority.shape == (2, 3)
    torch.testing.assert_close(priority.reshape(6), priority_flat)
    for key in ("loss_value", "loss_actor", "value_reward", "value_penalty"):
        torch.testing.assert_close(out[key], out_flat[key], msg=key)


def test_losses_read_the_parameters_they_are_given():  # _value_terms _5, _7
    # Target critic parameters handed to losses() (a stack's row, under vmap) make its targets,
    # not the loss's own: the same numbers as a loss that holds them itself.
    loss, batch = _loss(), _batch(4)
    params = loss.network_params().clone()
    with torch.no_grad():
        for p in params["target_value"].values(True, True):
            p.add_(0.3 * torch.randn(p.shape, generator=torch.Generator().manual_seed(2)))
    given, _ = loss.losses(batch, params)
    own, _ = loss.losses(batch, loss.network_params())
    assert not torch.allclose(given["loss_value"], own["loss_value"])
    with torch.no_grad():
        for key, value in params["target_value"].items(True, True):
            loss.target_value_network_params[key].copy_(value)
    held, _ = loss.losses(batch, loss.network_params())
    torch.testing.assert_close(given["loss_value"], held["loss_value"])


def test_a_nested_reward_key_names_its_losses_with_underscores():  # losses _19, _20, _21
    loss = _loss(keys=("reward", ("extra", "bonus")))
    batch = _batch(4)
    batch["next", "extra", "bonus"] = batch["next", "penalty"]
    out = loss(batch)
    assert {"loss_value_reward", "loss_value_extra_bonus", "value_extra_bonus"} <= set(out.keys())


def test_the_default_discount_is_0_99():  # make_value_estimator _1
    loss = MultiHeadD4PGLoss(make_actor(OBS, ACT, hidden=(8,)), make_critic(OBS, ACT, 1, (8,), 11),
                             reward_keys=["reward"])  # fmt: skip
    loss.make_value_estimator()
    assert loss.value_estimator.gamma == 0.99


def test_another_estimator_is_refused_naming_the_loss():  # make_value_estimator _4
    from torchrl.objectives.utils import ValueEstimators

    with pytest.raises(NotImplementedError, match=r"^MultiHeadD4PGLoss supports TD0 only"):
        _loss().make_value_estimator(ValueEstimators.GAE)


def test_torchrls_loss_mask_leaves_masked_rows_out_of_both_losses():
    # _value_terms _31, _34 and _actor_terms _36, _39 (the batch not passed to _reduce_loss):
    # with the pinned TorchRL a batch's ("collector", "mask") drops its rows from the means.
    loss, batch = _loss(), _batch(4)
    masked = batch.clone()
    masked["collector", "mask"] = torch.tensor([True, False, True, False])
    out, _ = loss.losses(masked, loss.network_params())
    kept, _ = loss.losses(batch[torch.tensor([0, 2])], loss.network_params())
    for key in ("loss_value", "loss_actor"):
        torch.testing.assert_close(out[key], kept[key], msg=key)
