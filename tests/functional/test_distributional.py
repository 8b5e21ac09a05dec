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


def test_a_support_per_entry_of_a_two_dim_batch():
    # z_j = v_min + j (v_max - v_min) / (N - 1) for each of [2, 2] bounds: the atoms on the last dim.
    v_min = torch.tensor([[-1.0, 0.0], [-2.0, 10.0]])
    v_max = torch.tensor([[1.0, 4.0], [0.0, 12.0]])
    expected = torch.tensor(
        [[[-1.0, 0.0, 1.0], [0.0, 2.0, 4.0]], [[-2.0, -1.0, 0.0], [10.0, 11.0, 12.0]]]
    )
    torch.testing.assert_close(categorical_support(v_min, v_max, 3), expected)


def test_the_support_and_the_projection_stay_on_their_inputs_device():
    # The meta device stands in for a GPU: a tensor built on the CPU instead cannot be mixed in.
    meta = torch.device("meta")
    atoms = categorical_support(torch.zeros(3, device=meta), torch.ones(3, device=meta), 5)
    assert atoms.device == meta and atoms.shape == (3, 5)
    probs = torch.ones(4, 5, device=meta) / 5
    reward, discount = torch.zeros(4, device=meta), torch.ones(4, device=meta)
    out = categorical_projection(probs, reward, discount, v_min=-1.0, v_max=1.0)
    assert out.device == meta and out.shape == (4, 5)


def test_two_atoms_are_enough():
    # Atoms 0 and 1, d = 0: every atom moves to r = 0.25 -> 0.75 on atom 0, 0.25 on atom 1.
    out = categorical_projection(
        torch.tensor([0.5, 0.5]), torch.tensor(0.25), torch.tensor(0.0), v_min=0.0, v_max=1.0
    )
    torch.testing.assert_close(out, torch.tensor([0.75, 0.25]))


def test_the_single_atom_refusal_names_the_shape():
    with pytest.raises(
        ValueError, match=r"^next_probs needs at least 2 atoms on its last dim, got"
    ):
        categorical_projection(
            torch.ones(4, 1), torch.zeros(4), torch.ones(4), v_min=-1.0, v_max=1.0
        )


@pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float64])
def test_the_projection_keeps_the_dtype_of_next_probs(dtype):
    # p = [0.2, 0.3, 0.5] on atoms -1, 0, 1 with r = 0.5, d = 0.5 move to 0, 0.5, 1:
    # atom 0 gets 0.2 + 0.15, atom 1 gets 0.15 + 0.5.
    probs = torch.tensor([0.2, 0.3, 0.5], dtype=dtype)
    half = torch.tensor(0.5, dtype=dtype)
    out = categorical_projection(probs, half, half, **SUPPORT3)
    assert out.dtype == dtype
    torch.testing.assert_close(out, torch.tensor([0.0, 0.35, 0.65], dtype=dtype))


def test_float_bounds_keep_float64_precision():
    # Support [0.1, 0.5] with 5 atoms (0.1, 0.2, 0.3, 0.4, 0.5; none exact in binary): d = 0 and
    # r = 0.1 + 2 (0.4 / 4), computed as the support computes it, lands on atom 2 in float64.
    # Bounds rounded to float32 on the way would move it by ~1e-9 and leak mass to atom 1 or 3.
    v_min, v_max = 0.1, 0.5
    delta = torch.tensor(v_max, dtype=torch.float64) - torch.tensor(v_min, dtype=torch.float64)
    reward = torch.tensor(v_min, dtype=torch.float64) + delta / 4 * 2
    probs = torch.full((5,), 0.2, dtype=torch.float64)
    out = categorical_projection(probs, reward, torch.zeros((), dtype=torch.float64), v_min, v_max)
    expected = torch.tensor([0.0, 0.0, 1.0, 0.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(out, expected, atol=1e-12, rtol=0)


def test_a_reward_far_beyond_the_support_puts_exactly_all_mass_on_the_top_atom():
    # T z_j = clip(r + d z_j, v_min, v_max) (Bellemare et al. 2017, Alg. 1): a target of 1e8 is
    # v_max, every atom's mass on the last one and nothing elsewhere, in float32.
    probs = torch.tensor([0.25, 0.25, 0.5])
    out = categorical_projection(probs, torch.tensor(1e8), torch.tensor(0.99), **SUPPORT3)
    assert torch.equal(out, torch.tensor([0.0, 0.0, 1.0]))


def test_no_atom_gets_negative_mass_where_the_top_atom_rounds_past_its_index():
    # On [-0.1, 0.7] with 12 atoms, (v_max - v_min) / delta is 11 + 9.5e-7 in float32: a clipped
    # atom lands a hair past the last index. Its mass stays there; no neighbour gets -1e-7.
    probs = torch.full((12,), 1 / 12)
    out = categorical_projection(probs, torch.tensor(5.0), torch.tensor(0.9), v_min=-0.1, v_max=0.7)
    assert (out >= 0).all() and (out[:-1] == 0).all()
    assert out[-1].item() == pytest.approx(1.0, abs=1e-6)


def test_a_tensor_bound_with_a_float_bound_is_not_read():
    # A support per head from a tensor v_min and one float v_max: the tensor is the caller's to
    # check (reading it would wait for its device), so a [2] tensor with a float passes unread.
    v_min = torch.tensor([-1.0, -3.0])  # atoms -1, 0, 1 and -3, -1, 1
    probs = torch.tensor([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    out = categorical_projection(probs, torch.tensor(0.5), torch.tensor(1.0), v_min, 1.0)
    # head 0: 0 -> 0.5, half on 0, half on 1; head 1: -1 -> -0.5, 3/4 on -1, 1/4 on 1.
    torch.testing.assert_close(out, torch.tensor([[0.0, 0.5, 0.5], [0.0, 0.75, 0.25]]))


def test_the_top_atom_index_stays_in_range_where_bfloat16_rounds_it_past_the_end():
    # 191 atoms on [-1, 1] in bfloat16: delta = 2 / 190 rounds so that v_max sits at position
    # 191.0, one past the last index (190). A clipped atom's mass must still land on atom 190.
    probs = torch.zeros(191, dtype=torch.bfloat16)
    probs[95] = 1.0  # atom 95 (z = 0) moves to 10, clipped to v_max
    one = torch.tensor(1.0, dtype=torch.bfloat16)
    out = categorical_projection(probs, 10 * one, one, v_min=-1.0, v_max=1.0)
    assert out[-1].item() == 1.0 and (out[:-1] == 0).all()


@pytest.mark.parametrize("bad", ["reward", "discount"])
def test_a_nan_reward_or_discount_is_named_not_an_index_of_minus_two_to_the_63(bad):
    """The finding: a NaN reward failed as "index -9223372036854775808 is out of bounds"."""
    probs = torch.full((2, 5), 0.2)
    values = {"reward": torch.tensor([0.5, 0.5]), "discount": torch.tensor([0.9, 0.9])}
    values[bad] = torch.tensor([0.5, float("nan")])
    with pytest.raises(ValueError, match="a reward or discount is NaN"):
        categorical_projection(probs, values["reward"], values["discount"], -1.0, 1.0)
    inf = categorical_projection(probs, torch.tensor([float("inf")] * 2), torch.zeros(2), -1.0, 1.0)
    assert torch.equal(inf, torch.tensor([[0.0, 0, 0, 0, 1]] * 2))  # +inf: clipped to v_max
