"""MultiHeadD4PGLoss: targets, per-head losses, gradients, target updates, learning a bandit."""

import pytest
import torch
from tensordict import TensorDict
from torchrl.objectives import HardUpdate
from torchrl.objectives.utils import ValueEstimators

from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss

OBS, ACT = 3, 1


def _loss(heads=2, v=(-10.0, 10.0), atoms=21, gamma=0.99, **kwargs):
    torch.manual_seed(0)
    keys = ["reward", "penalty", "extra"][:heads]
    actor = make_actor(OBS, ACT, hidden=(32, 32))
    critic = make_critic(OBS, ACT, heads, (64, 64), atoms, v_min=v[0], v_max=v[1])
    loss = MultiHeadD4PGLoss(actor, critic, reward_keys=keys, **kwargs)
    loss.make_value_estimator(gamma=gamma)
    return loss


def _batch(n=8, reward=1.0, penalty=-2.0, terminated=True, action=None, steps=None):
    td = TensorDict(
        {
            "observation": torch.ones(n, OBS),
            "action": torch.zeros(n, ACT) if action is None else action,
            "next": {
                "observation": torch.ones(n, OBS),
                "reward": torch.full((n, 1), reward),
                "penalty": torch.full((n, 1), penalty),
                "terminated": torch.full((n, 1), terminated),
            },
        },
        [n],
    )
    if steps is not None:
        td["steps_to_next_obs"] = torch.full((n,), steps)
    return td


def test_terminal_target_is_the_reward_of_each_head():
    # Atoms every 1.0 on [-10, 10]: reward 1 -> all mass on atom 11, penalty -2 -> atom 8;
    # a reward of 0.25 puts 0.75 on atom 10 and 0.25 on atom 11.
    loss = _loss()
    target = loss.target_distribution(_batch(reward=0.25, penalty=-2.0))
    assert target.shape == (8, 2, 21)
    torch.testing.assert_close(target[0, 0, 10:12], torch.tensor([0.75, 0.25]))
    assert target[0, 1, 8].item() == pytest.approx(1.0)


def _target_mean(loss, td, gamma_n):
    """gamma_n * E[Z'] per head, from the target actor and target critics."""
    with torch.no_grad():
        nxt = td["next"].select("observation").clone()
        with loss.target_actor_network_params.to_module(loss.actor_network):
            loss.actor_network(nxt)
        with loss.target_value_network_params.to_module(loss.value_network):
            z = loss.value_network(nxt)["state_action_value_logits"].softmax(-1)
    return gamma_n * (z * torch.linspace(-10, 10, 21)).sum(-1)


def test_non_episodic_heads_bootstrap_through_termination():
    # Terminal, n = 2, gamma = 0.5: the episodic task head's target is its reward alone; the
    # non-episodic penalty head's is r + 0.25 * E[Z'] as if the episode went on.
    loss = _loss(gamma=0.5, non_episodic_keys=["penalty"])
    td = _batch(terminated=True, steps=2)
    mean = (loss.target_distribution(td) * torch.linspace(-10, 10, 21)).sum(-1)
    bootstrap = _target_mean(loss, td, 0.25)
    torch.testing.assert_close(mean[:, 0], torch.full((8,), 1.0), atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(mean[:, 1], -2.0 + bootstrap[:, 1], atol=1e-5, rtol=1e-5)
    with pytest.raises(ValueError, match=r"non_episodic_keys \['icm_reward'\] are not reward"):
        _loss(non_episodic_keys=["icm_reward"])


def test_target_policy_smoothing_perturbs_each_targets_action():
    # Non-terminal rows with the same next observation: without noise every row has the same
    # target; with TD3 smoothing each row bootstraps from its own noisy action; a zero clip
    # removes the noise again.
    td = _batch(terminated=False)
    plain = _loss().target_distribution(td)
    torch.testing.assert_close(plain, plain[:1].expand_as(plain))
    smoothed = _loss(policy_noise=0.2).target_distribution(td)
    assert (smoothed - smoothed[:1]).abs().amax(dim=(1, 2)).gt(1e-4)[1:].all()
    torch.testing.assert_close(
        _loss(policy_noise=0.2, noise_clip=0.0).target_distribution(td), plain
    )
    with pytest.raises(ValueError, match="policy_noise and noise_clip must be >= 0, got -0.1"):
        _loss(policy_noise=-0.1)


def test_per_head_support_caps_the_penalty_critic_at_zero():
    # Task head on [-10, 10], penalty head on [-10, 0] (21 atoms: 0.5 apart). A terminal penalty
    # of -2 lands on the penalty head's atom 16; the penalty critic's value is <= 0 whatever its
    # logits, so the actor can never be promised a positive penalty value.
    loss = _loss(v=(-10.0, [10.0, 0.0]))
    target = loss.target_distribution(_batch(reward=1.0, penalty=-2.0))
    assert target[0, 0, 11].item() == pytest.approx(1.0)
    assert target[0, 1, 16].item() == pytest.approx(1.0)
    values = loss(_batch())["value_penalty"]
    assert -10.0 <= values.item() <= 0.0


def test_bootstrap_uses_gamma_to_the_n():
    # Non-terminal, n = 3 steps, gamma = 0.5: discount 0.125; the target mean is
    # r + 0.125 * E[Z'] for each head (no clipping inside [-10, 10]).
    loss = _loss(gamma=0.5)
    td = _batch(terminated=False, steps=3)
    support = torch.linspace(-10, 10, 21)
    expected = torch.tensor([1.0, -2.0]) + _target_mean(loss, td, 0.125)
    mean = (loss.target_distribution(td) * support).sum(-1)
    torch.testing.assert_close(mean, expected, atol=1e-5, rtol=1e-5)


def test_losses_priorities_and_head_names():
    loss = _loss()
    td = _batch()
    out = loss(td)
    assert {"loss_actor", "loss_value", "loss_value_reward", "loss_value_penalty"} <= set(
        out.keys()
    )
    torch.testing.assert_close(
        out["loss_value"], out["loss_value_reward"] + out["loss_value_penalty"]
    )
    assert td["td_error"].shape == (8,) and (td["td_error"] > 0).all()


def test_actor_loss_does_not_train_the_critic_and_vice_versa():
    loss = _loss()
    out = loss(_batch())
    out["loss_actor"].backward()
    assert all(
        p.grad is None or p.grad.abs().sum() == 0
        for p in loss.value_network_params.values(True, True)
    )
    assert any(
        p.grad is not None and p.grad.abs().sum() > 0
        for p in loss.actor_network_params.values(True, True)
    )
    loss.zero_grad()
    out = loss(_batch())
    out["loss_value"].backward()
    assert all(
        p.grad is None or p.grad.abs().sum() == 0
        for p in loss.actor_network_params.values(True, True)
    )


def test_priority_weights_give_torchrls_weighted_mean():
    # TorchRL reduces with sum(w * l) / sum(w): zero-weight samples drop out of the loss.
    loss = _loss()
    td = _batch()
    td["next", "reward"][4:] = 5.0
    first_half = loss(td[:4].clone())["loss_value"]
    td["priority_weight"] = torch.tensor([1.0] * 4 + [0.0] * 4)
    torch.testing.assert_close(loss(td)["loss_value"], first_half)


def test_head_count_mismatch_is_a_clear_error():
    actor = make_actor(OBS, ACT, hidden=(8,))
    critic = make_critic(OBS, ACT, num_heads=3, hidden=(8,), num_atoms=5)
    loss = MultiHeadD4PGLoss(actor, critic, reward_keys=["reward", "penalty"])
    with pytest.raises(ValueError, match="3 heads but there are 2 reward keys"):
        loss(_batch())
    with pytest.raises(ValueError, match="reward_keys"):
        MultiHeadD4PGLoss(actor, critic, reward_keys=[])
    with pytest.raises(ValueError, match="gamma must be in"):
        loss.make_value_estimator(gamma=1.5)
    with pytest.raises(NotImplementedError, match="TD0 only"):
        loss.make_value_estimator(ValueEstimators.GAE)


def test_value_and_actor_losses_are_callable_alone_and_sum_to_forward():
    loss = _loss()
    td = _batch()
    value, info = loss.loss_value(td.clone())
    actor, actor_info = loss.loss_actor(td.clone())
    out = loss(td)
    torch.testing.assert_close(value, out["loss_value"])
    torch.testing.assert_close(actor, out["loss_actor"])
    torch.testing.assert_close(info["per_head"][1], out["loss_value_penalty"])
    # The actor loss is minus the summed head values at (s, pi(s)).
    torch.testing.assert_close(actor, -actor_info["value"].sum())


def test_reward_keys_are_renamed_with_set_keys():
    loss = _loss()
    td = _batch(reward=1.0, penalty=-2.0)
    td["next", "force_penalty"] = td["next", "penalty"].clone()
    before = loss.target_distribution(td)
    loss.set_keys(rewards=("reward", "force_penalty"))
    assert loss.reward_keys == ["reward", "force_penalty"]
    assert set(loss(td.clone()).keys()) >= {"loss_value_force_penalty", "value_force_penalty"}
    torch.testing.assert_close(loss.target_distribution(td), before)
    with pytest.raises(ValueError, match="one reward per critic head"):
        loss.set_keys(rewards=("reward",))


def test_hard_update_copies_online_into_target_after_the_interval():
    loss = _loss()
    updater = HardUpdate(loss, value_network_update_interval=3)
    with torch.no_grad():
        for p in loss.value_network_params.values(True, True):
            p.add_(1.0)
    online = loss.value_network_params.clone()
    # TorchRL's HardUpdate counts `interval` steps, then copies on the next one.
    for _ in range(3):
        updater.step()
    assert not torch.allclose(
        loss.target_value_network_params["module", "head", "weight"],
        online["module", "head", "weight"],
    )
    updater.step()
    for key, value in online.items(True, True):
        torch.testing.assert_close(loss.target_value_network_params[key], value)


def test_critics_learn_per_head_values_and_actor_maximises_their_sum():
    # A one-step bandit: head 0 pays -(a - 0.6)^2, head 1 pays -(a + 0.2)^2 (terminal).
    # The sum -(a-0.6)^2 - (a+0.2)^2 peaks at a = 0.2, while each head alone peaks elsewhere.
    loss = _loss(heads=2, v=(-2.0, 1.0), atoms=31, delay_actor=False)
    opt_critic = torch.optim.Adam(loss.value_network_params.values(True, True), lr=3e-3)
    opt_actor = torch.optim.Adam(loss.actor_network_params.values(True, True), lr=1e-3)
    updater = HardUpdate(loss, value_network_update_interval=1)
    gen = torch.Generator().manual_seed(0)
    for _ in range(600):
        a = torch.rand(64, ACT, generator=gen) * 2 - 1
        td = _batch(64, action=a)
        td["next", "reward"] = -((a - 0.6) ** 2)
        td["next", "penalty"] = -((a + 0.2) ** 2)
        out = loss(td)
        opt_critic.zero_grad()
        opt_actor.zero_grad()
        (out["loss_value"] + out["loss_actor"]).backward()  # the losses touch disjoint params
        opt_critic.step()
        opt_actor.step()
        updater.step()
    action = loss.actor_network(_batch(1).select("observation"))["action"].item()
    assert action == pytest.approx(0.2, abs=0.1)
    # value_<key> is each head's E[Q_k(s, pi(s))]: at a = 0.2 both components pay -0.16.
    out = loss(_batch(1))
    assert out["value_reward"].item() == pytest.approx(-0.16, abs=0.08)
    assert out["value_penalty"].item() == pytest.approx(-0.16, abs=0.08)
