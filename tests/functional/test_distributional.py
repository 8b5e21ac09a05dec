"""categorical_projection against hand-computed C51 projections."""

import pytest
import torch

from gentlerl.functional.distributional import categorical_projection, categorical_support

SUPPORT3 = dict(v_min=-1.0, v_max=1.0)  # atoms at -1, 0, 1; delta z = 1


def test_half_atom_shift_splits_mass_between_neighbours():
    # All mass on atom 0; r = 0.5, d = 1 moves it to 0.5 → half on atom 0, half on atom 1.
    out = categorical_projection(
        torch.tensor([0.0, 1.0, 0.0]), torch.tensor(0.5), torch.tensor(1.0), **SUPPORT3
    )
    torch.testing.assert_close(out, torch.tensor([0.0, 0.5, 0.5]))


def test_terminal_transition_puts_all_mass_at_reward():
    # d = 0: every atom moves to r = 0.25 → 0.75 on atom 0, 0.25 on atom 1, whatever next_probs is.
    probs = torch.tensor([[0.2, 0.3, 0.5], [1.0, 0.0, 0.0]])
    out = categorical_projection(probs, torch.tensor([0.25, 0.25]), torch.zeros(2), **SUPPORT3)
    torch.testing.assert_close(out, torch.tensor([[0.0, 0.75, 0.25]] * 2))


def test_rewards_outside_the_support_are_clipped_to_its_ends():
    probs = torch.tensor([[0.2, 0.3, 0.5], [0.2, 0.3, 0.5]])
    out = categorical_projection(
        probs, torch.tensor([10.0, -10.0]), torch.tensor([0.99, 0.99]), **SUPPORT3
    )
    torch.testing.assert_close(out, torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))


def test_discount_contracts_the_distribution():
    # d = 0.5, r = 0: atoms -1, 0, 1 move to -0.5, 0, 0.5.
    # p = [0.2, 0.3, 0.5] → atom -1 gets 0.1, atom 0 gets 0.1 + 0.3 + 0.25, atom 1 gets 0.25.
    out = categorical_projection(
        torch.tensor([0.2, 0.3, 0.5]), torch.tensor(0.0), torch.tensor(0.5), **SUPPORT3
    )
    torch.testing.assert_close(out, torch.tensor([0.1, 0.65, 0.25]))


def test_mass_and_mean_are_conserved_inside_the_support():
    gen = torch.Generator().manual_seed(0)
    probs = torch.softmax(torch.randn(64, 4, 51, generator=gen), -1)
    reward = torch.rand(64, 4, generator=gen) * 2 - 1
    discount = torch.full((64, 1), 0.9)  # broadcasts over the 4 heads
    out = categorical_projection(probs, reward, discount, v_min=-10.0, v_max=10.0)
    support = torch.linspace(-10.0, 10.0, 51)
    torch.testing.assert_close(out.sum(-1), torch.ones(64, 4))
    expected_mean = reward + 0.9 * (probs * support).sum(-1)
    torch.testing.assert_close((out * support).sum(-1), expected_mean, atol=1e-4, rtol=1e-4)


def test_a_support_per_head():
    # Head 0 on [-1, 1] (atoms -1, 0, 1), head 1 on [-2, 0] (atoms -2, -1, 0). The same next
    # distribution [0, 1, 0] with r = -0.5, d = 1: head 0's atom 0 moves to -0.5 (half on -1,
    # half on 0); head 1's atom -1 moves to -1.5 (half on -2, half on -1).
    v_min, v_max = torch.tensor([-1.0, -2.0]), torch.tensor([1.0, 0.0])
    torch.testing.assert_close(
        categorical_support(v_min, v_max, 3), torch.tensor([[-1.0, 0.0, 1.0], [-2.0, -1.0, 0.0]])
    )
    probs = torch.tensor([[0.0, 1.0, 0.0]]).expand(2, 3)
    out = categorical_projection(probs, torch.tensor(-0.5), torch.tensor(1.0), v_min, v_max)
    torch.testing.assert_close(out, torch.tensor([[0.5, 0.5, 0.0], [0.5, 0.5, 0.0]]))
    # A reward of +1 is clipped at each head's own top: atom 1 for head 0, atom 0 for head 1.
    out = categorical_projection(probs, torch.tensor(1.0), torch.tensor(0.0), v_min, v_max)
    torch.testing.assert_close(out, torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]))


@pytest.mark.parametrize(("v_min", "v_max"), [(1.0, 1.0), (2.0, -2.0), (float("nan"), 1.0)])
def test_bad_support_raises(v_min, v_max):
    with pytest.raises(ValueError, match="v_min"):
        categorical_projection(
            torch.ones(3) / 3, torch.tensor(0.0), torch.tensor(1.0), v_min=v_min, v_max=v_max
        )


def test_single_atom_raises():
    with pytest.raises(ValueError, match="at least 2 atoms"):
        categorical_projection(
            torch.ones(1), torch.tensor(0.0), torch.tensor(1.0), v_min=-1.0, v_max=1.0
        )
