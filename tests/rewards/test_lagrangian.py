"""Method IV's trade-off: the excess cost, the (1 + lambda) weights, the per-head normalisation,
the PID Lagrangian with its warm-up, and a toy problem whose learned trade-off does not move when
a component's units are multiplied by 10."""

import math

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.functional import excess_cost, lagrangian_weights, normalized_values
from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.rewards.lagrangian import CostLagrangian, constrained_head, head_weights


def test_the_excess_cost_is_the_hinge_in_tolerances_capped_at_one():
    # T = 2: sites at 3, 1 and 2.5 N exceed it by 1 and 0.5 -> (1 + 0.5) / 2 = 0.75.
    cost = excess_cost(torch.tensor([[3.0, 1.0, 2.5], [9.0, 0.0, 0.0], [2.0, 2.0, 0.0]]), 2.0)
    torch.testing.assert_close(cost, torch.tensor([0.75, 1.0, 0.0]))  # 9 N: 3.5 -> capped at 1
    # Units cannot tip it: the same impacts in a unit 10x smaller, with T stated in it.
    impacts = torch.tensor([[3.0, 1.0, 2.5]])
    torch.testing.assert_close(excess_cost(impacts * 10, 20.0), excess_cost(impacts, 2.0))
    with pytest.raises(ValueError, match="tolerance must be a finite impact > 0"):
        excess_cost(impacts, 0.0)


def test_the_weights_are_one_and_lambda_over_one_plus_lambda():
    assert lagrangian_weights(0.0) == (1.0, 0.0)
    assert lagrangian_weights(3.0) == (0.25, 0.75)  # 1/4 and 3/4
    assert sum(lagrangian_weights(1e6)) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="multiplier must be >= 0"):
        lagrangian_weights(-1.0)
    # The constrained head: the excess penalty where learned, else the paper's penalty.
    assert head_weights([keys.REWARD, keys.EXCESS_PENALTY], 1.0) == [0.5, 0.5]
    assert head_weights([keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE], 3.0) == [
        0.25, 0.75, 0.25,
    ]  # fmt: skip
    assert constrained_head([keys.REWARD, keys.PENALTY, keys.EXCESS_PENALTY]) == "excess_penalty"
    with pytest.raises(ValueError, match="have neither"):
        constrained_head([keys.REWARD])


def test_normalized_values_divide_by_the_batch_magnitude_with_a_floor():
    q = torch.tensor([[2.0, -0.001], [4.0, 0.0], [-6.0, 0.001]])  # mean |Q|: 4 and 2/3e-3
    span = torch.tensor([20.0, 10.0])  # floors 0.2 and 0.1
    expected = torch.tensor([[0.5, -0.01], [1.0, 0.0], [-1.5, 0.01]])
    torch.testing.assert_close(normalized_values(q, span), expected)
    torch.testing.assert_close(normalized_values(q * 10, span * 10), expected)  # any unit
    q.requires_grad_(True)
    normalized_values(q, span)[:, 0].sum().backward()  # no gradient through the scale
    torch.testing.assert_close(q.grad[:, 0], torch.full((3,), 0.25))


def test_the_pid_waits_for_the_warmup_then_steps_on_the_windows_mean():
    lag = CostLagrangian(limit=5.0, gains=(0.1, 0.01, 0.0), warmup_frames=1000, window=2)
    assert lag.observe([20.0, 30.0], frames=500) == 0.0  # warm-up: the window fills, no step
    assert lag.steps == 0 and list(lag.recent) == [20.0, 30.0]
    # After it: mean(30, 10) = 20, e = 15 -> I = 0.15, lambda = 0.1 * 15 + 0.15 = 1.65.
    assert lag.observe([10.0], frames=1000) == pytest.approx(1.65)
    assert lag.weights([keys.REWARD, keys.EXCESS_PENALTY]) == pytest.approx([1 / 2.65, 1.65 / 2.65])
    # mean(10, 0) = 5: at the limit, e = 0 -> lambda = the integral, 0.15.
    assert lag.observe([0.0], frames=1200) == pytest.approx(0.15)
    with pytest.raises(ValueError, match="an episode's cost must be finite and >= 0, got nan"):
        lag.observe([math.nan], frames=1300)
    assert lag.episodes == 4  # the refused batch took nothing


def test_the_state_round_trips_and_refuses_a_corrupt_entry():
    lag = CostLagrangian(limit=1.0, gains=(0.1, 0.01, 0.01))
    lag.observe([4.0, 2.0], frames=0)
    other = CostLagrangian(limit=1.0, gains=(0.1, 0.01, 0.01))
    other.load_state_dict(lag.state_dict())
    assert other.state_dict() == lag.state_dict()
    for name, bad in (("multiplier", -1.0), ("integral", 1e9), ("recent", [math.inf])):
        with pytest.raises(ValueError, match=f"CostLagrangian state '{name}'="):
            other.load_state_dict({**lag.state_dict(), name: bad})
    with pytest.raises(ValueError, match="'steps'='<missing>' must be an integer >= 0"):
        other.load_state_dict({k: v for k, v in lag.state_dict().items() if k != "steps"})
    assert other.state_dict() == lag.state_dict()  # unchanged by the refusals


# A toy trade-off: one action a in [-1, 1] per state; the task pays (1 + a) / 2 a step, the cost
# head charges -relu(a) (pressing harder earns more and costs more). Terminal one-step episodes,
# so the critics learn each head's immediate reward; lambda fixed at 1.


def _toy_run(reward_unit: float, cost_unit: float, normalize: bool, updates: int = 150):
    torch.manual_seed(0)
    actor = make_actor(2, 1, hidden=(16,))
    critic = make_critic(
        2, 1, 2, (32,), 21, v_min=[-0.1 * reward_unit, -1.1 * cost_unit],
        v_max=[1.1 * reward_unit, 0.0],
    )  # fmt: skip
    loss = MultiHeadD4PGLoss(
        actor, critic, reward_keys=[keys.REWARD, keys.EXCESS_PENALTY], normalize_values=normalize
    )
    loss.make_value_estimator(gamma=0.99)
    for key, weight in zip(loss.reward_keys, head_weights(loss.reward_keys, 1.0), strict=True):
        loss.set_head_weight(key, weight)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    generator = torch.Generator().manual_seed(1)
    for _ in range(updates):
        obs = torch.rand(64, 2, generator=generator)
        action = torch.rand(64, 1, generator=generator) * 2 - 1
        td = TensorDict(
            {
                "observation": obs,
                "action": action,
                "next": {
                    "observation": obs,
                    keys.REWARD: reward_unit * (1 + action) / 2,
                    keys.EXCESS_PENALTY: -cost_unit * action.clamp_min(0),
                    "terminated": torch.ones(64, 1, dtype=torch.bool),
                },
            },
            [64],
        )
        optim.zero_grad()
        out = loss(td)
        (out["loss_actor"] + out["loss_value"]).backward()
        optim.step()
    with torch.no_grad():
        probe = TensorDict({"observation": torch.rand(16, 2, generator=generator)}, [16])
        return actor(probe)["action"]


def test_ten_times_the_units_of_a_component_leave_the_learned_trade_off_unchanged():
    base = _toy_run(1.0, 1.0, normalize=True)
    for reward_unit, cost_unit in ((10.0, 1.0), (1.0, 10.0)):
        torch.testing.assert_close(
            _toy_run(reward_unit, cost_unit, normalize=True), base, atol=1e-5, rtol=0
        )
    # Without the normalisation the same 10x moves the trade-off: the test can tell.
    plain = _toy_run(1.0, 1.0, normalize=False)
    assert (_toy_run(1.0, 10.0, normalize=False) - plain).abs().max() > 0.1
