"""CategoricalTD0: the D4PG critic target (Barth-Maron et al. 2018, eq. 7) by hand."""

import pytest
import torch

from gentlerl.functional import categorical_projection
from gentlerl.objectives.value import CategoricalTD0


def test_the_discount_is_gamma_by_default_and_may_be_zero_or_one():
    assert CategoricalTD0().gamma == 0.99
    assert CategoricalTD0(0.0).gamma == 0.0  # bandit targets: the reward alone
    assert CategoricalTD0(1.0).gamma == 1.0  # undiscounted
    for bad in (-0.1, 1.01):
        with pytest.raises(ValueError, match=r"gamma must be in \[0, 1\]"):
            CategoricalTD0(bad)


def test_the_target_moves_each_heads_atoms_by_its_return_and_gamma_to_the_n():
    # Atoms -1, 0, 1 for both heads; Z' all on z = 1 (logits 0, -1e9, ... give exactly 1 there).
    # Head 0: R = 0, gamma^n = 0.9^3 = 0.729 -> 0.729 lies between atoms 0 and 1:
    #   0.271 on z = 0, 0.729 on z = 1.
    # Head 1: cut (terminal): R = -0.5 alone -> half on z = -1, half on z = 0.
    f64 = torch.float64
    atoms = torch.tensor([-1.0, 0.0, 1.0], dtype=f64).expand(1, 2, 3)
    logits = torch.tensor([-1e9, -1e9, 0.0], dtype=f64).expand(1, 2, 3)
    reward = torch.tensor([[0.0, -0.5]], dtype=f64)
    steps = torch.tensor([[3]])
    cut = torch.tensor([[False, True]])
    out = CategoricalTD0(0.9).target(logits, atoms, reward, steps, cut)
    gamma_n = 0.9**3
    expected = torch.tensor([[[0.0, 1 - gamma_n, gamma_n], [0.5, 0.5, 0.0]]], dtype=f64)
    # float64 all the way: gamma^n taken in float32 (0.72899997) would be off by 3e-8.
    torch.testing.assert_close(out, expected, atol=1e-12, rtol=0)
    torch.testing.assert_close(
        out,
        categorical_projection(
            logits.softmax(-1), reward, torch.tensor([[gamma_n, 0.0]], dtype=f64), -1.0, 1.0
        ),
        atol=1e-12,
        rtol=0,
    )
