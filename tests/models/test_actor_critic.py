"""Actor and fused multi-head critic: architecture, shapes, equivalence to K separate critics."""

import pytest
import torch
from tensordict import TensorDict
from torch import nn

from gentlerl import keys
from gentlerl.models import FusedCritic, make_actor, make_critic, make_exploration_policy


def test_actor_architecture_and_range():
    actor = make_actor(63, 20)
    net = actor.module
    # Linear(63,300) LayerNorm Tanh Linear(300,200) ELU Linear(200,20) Tanh
    kinds = [type(m) for m in net]
    assert kinds == [nn.Linear, nn.LayerNorm, nn.Tanh, nn.Linear, nn.ELU, nn.Linear, nn.Tanh]
    assert (net[0].in_features, net[0].out_features, net[3].out_features) == (63, 300, 200)
    td = actor(TensorDict({keys.OBSERVATION: 100 * torch.randn(32, 63)}, [32]))
    assert td[keys.ACTION].shape == (32, 20)
    assert td[keys.ACTION].abs().max() <= 1.0


def test_exploration_noise_has_sigma_03_and_stays_in_bounds():
    torch.manual_seed(0)
    actor = make_actor(4, 3, hidden=(8,))
    with torch.no_grad():  # a zero last layer makes the clean action exactly 0
        actor.module[-2].weight.zero_()
        actor.module[-2].bias.zero_()
    policy = make_exploration_policy(actor, sigma=0.3)
    noisy = policy(TensorDict({keys.OBSERVATION: torch.randn(20000, 4)}, [20000]))[keys.ACTION]
    assert noisy.abs().max() <= 1.0
    # N(0, 0.3^2) noise; clipping at +-1 (3.3 sigma) changes the std by < 0.1 %.
    assert noisy.std().item() == pytest.approx(0.3, rel=0.02)
    assert noisy.mean().item() == pytest.approx(0.0, abs=0.01)
    with pytest.raises(ValueError, match="sigma"):
        make_exploration_policy(actor, sigma=-1.0)


def test_fused_critic_shapes_and_paper_defaults():
    critic = make_critic(63, 20, num_heads=4)
    td = TensorDict(
        {keys.OBSERVATION: torch.randn(5, 7, 63), keys.ACTION: torch.rand(5, 7, 20)}, [5, 7]
    )
    out = critic(td)
    assert out[keys.STATE_ACTION_VALUE_LOGITS].shape == (5, 7, 4, 101)
    # The paper's support: 101 atoms 2 apart on [-100, 100], for every head.
    atoms = out[keys.STATE_ACTION_VALUE_ATOMS]
    assert atoms.shape == (5, 7, 4, 101)
    torch.testing.assert_close(atoms[0, 0, 3], torch.linspace(-100.0, 100.0, 101))
    fused = critic.module
    assert [layer.weight.shape for layer in fused.layers] == [(4, 83, 400), (4, 400, 300)]
    assert fused.head.weight.shape == (4, 300, 101)


def _separate_critic(fused: FusedCritic, k: int) -> nn.Sequential:
    """Head k of the fused critic copied into a plain nn.Sequential of the paper's layers."""
    l0, l1, head, norm = fused.layers[0], fused.layers[1], fused.head, fused.norm
    seq = nn.Sequential(
        nn.Linear(l0.weight.shape[1], l0.weight.shape[2]),
        nn.LayerNorm(l0.weight.shape[2]),
        nn.Tanh(),
        nn.Linear(l1.weight.shape[1], l1.weight.shape[2]),
        nn.ELU(),
        nn.Linear(head.weight.shape[1], head.weight.shape[2]),
    )
    with torch.no_grad():
        for lin, src in ((seq[0], l0), (seq[3], l1), (seq[5], head)):
            lin.weight.copy_(src.weight[k].T)
            lin.bias.copy_(src.bias[k, 0])
        seq[1].weight.copy_(norm.weight[k, 0] + 0.1 * k)  # non-trivial affine per head
        seq[1].bias.copy_(norm.bias[k, 0] - 0.2 * k)
        norm.weight[k, 0].copy_(seq[1].weight)
        norm.bias[k, 0].copy_(seq[1].bias)
    return seq


def test_fused_critic_equals_k_separate_critics():
    torch.manual_seed(0)
    fused = FusedCritic(6, 2, num_heads=3, hidden=(16, 8), num_atoms=11)
    separate = [_separate_critic(fused, k) for k in range(3)]
    obs, act = torch.randn(10, 6), torch.randn(10, 2)
    out, _ = fused(obs, act)
    for k, seq in enumerate(separate):
        torch.testing.assert_close(out[:, k], seq(torch.cat([obs, act], -1)))


def test_heads_are_independent_in_init_and_gradient():
    torch.manual_seed(0)
    fused = FusedCritic(6, 2, num_heads=3, hidden=(16, 8), num_atoms=11)
    w = fused.layers[0].weight
    assert not torch.allclose(w[0], w[1])
    fused(torch.randn(4, 6), torch.randn(4, 2))[0][:, 1].sum().backward()
    for p in (fused.layers[0].weight, fused.layers[1].weight, fused.head.weight, fused.norm.weight):
        assert p.grad[1].abs().sum() > 0
        assert p.grad[0].abs().sum() == 0 and p.grad[2].abs().sum() == 0


@pytest.mark.parametrize(
    "kwargs", [dict(num_heads=0), dict(hidden=()), dict(hidden=(16, -1)), dict(num_atoms=1)]
)
def test_bad_sizes_raise(kwargs):
    args = dict(obs_dim=6, action_dim=2, num_heads=2) | kwargs
    with pytest.raises(ValueError):
        FusedCritic(**args)


def test_the_critic_owns_a_support_per_head():
    # Task head on [-10, 10], penalty head on [-10, 0]: 5 atoms, 5.0 and 2.5 apart.
    fused = FusedCritic(6, 2, num_heads=2, hidden=(8,), num_atoms=5, v_min=-10.0, v_max=[10.0, 0.0])
    expected = torch.tensor([[-10.0, -5.0, 0.0, 5.0, 10.0], [-10.0, -7.5, -5.0, -2.5, 0.0]])
    torch.testing.assert_close(fused.support, expected)
    _, atoms = fused(torch.randn(3, 6), torch.randn(3, 2))
    torch.testing.assert_close(atoms, expected.expand(3, 2, 5))
    assert not any("v_" in name for name in fused.state_dict())  # set by the config, not learned
    with pytest.raises(ValueError, match=r"v_max=\[10.0\] needs one value per head \(2 heads\)"):
        FusedCritic(6, 2, num_heads=2, v_min=-10.0, v_max=[10.0])
    with pytest.raises(ValueError, match="need v_min < v_max for every head"):
        FusedCritic(6, 2, num_heads=2, v_min=-10.0, v_max=[10.0, -20.0])


def test_the_critics_atoms_follow_a_loss_moved_to_another_dtype():
    """``loss.to(...)`` does not reach the critic's plain attributes: its atoms follow the logits
    (on a GPU: one move in the warm-up, none in a captured CUDA graph)."""
    from gentlerl.objectives import MultiHeadD4PGLoss

    critic = make_critic(3, 1, 2, (16,), 11, v_min=-5.0, v_max=[5.0, 0.0])
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=["a", "b"])
    loss = loss.to(torch.float64)
    td = TensorDict(
        {"observation": torch.randn(4, 3, dtype=torch.float64),
         "action": torch.rand(4, 1, dtype=torch.float64)}, [4]
    )  # fmt: skip
    with loss.value_network_params.to_module(loss.value_network):
        out = loss.value_network(td)
    atoms = out["state_action_value_atoms"]
    assert atoms.dtype == torch.float64 and atoms.shape == (4, 2, 11)
    torch.testing.assert_close(atoms[0, 1], torch.linspace(-5.0, 0.0, 11, dtype=torch.float64))
