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


def test_the_pid_waits_for_the_warmup_then_steps_once_a_period_on_the_windows_mean():
    lag = CostLagrangian(
        limit=5.0, gains=(0.1, 0.01, 0.0), warmup_frames=1000, window=2, period=200
    )
    for frames in (200, 400, 1000):  # warm-up (up to and at 1000): the window fills, no step
        assert lag.observe([20.0, 30.0], frames=frames) == 0.0
    assert lag.steps == 0 and list(lag.recent) == [20.0, 30.0]
    assert lag.observe([10.0], frames=1100) == 0.0  # no multiple of 200 crossed since 1000
    # 1200: mean(30, 10) = 20 = 4 limits, e = 3 -> I = 0.03, lambda = 0.1 * 3 + 0.03 = 0.33.
    assert lag.observe([], frames=1200) == pytest.approx(0.33)
    assert lag.weights([keys.REWARD, keys.EXCESS_PENALTY]) == pytest.approx([1 / 1.33, 0.33 / 1.33])
    # 1400: mean(10, 0) = 5, at the limit: e = 0 -> lambda = the integral, 0.03.
    assert lag.observe([0.0], frames=1400) == pytest.approx(0.03)
    assert lag.steps == 2
    with pytest.raises(ValueError, match="an episode's cost must be finite and >= 0, got nan"):
        lag.observe([1.0, math.nan], frames=1600)
    assert lag.episodes == 8 and lag.frames == 1400  # the refused batch took nothing


def test_the_error_is_in_limits_so_one_set_of_gains_serves_every_limit():
    hand, finger = (CostLagrangian(d, (1.0, 0.1, 0.0), period=1) for d in (1.0, 25.0))
    hand.observe([], frames=0), finger.observe([], frames=0)  # the first call only counts
    # Twice the limit on both: e = 1 -> lambda = 1 + 0.1.
    assert hand.observe([2.0], frames=1) == finger.observe([50.0], frames=1) == pytest.approx(1.1)
    with pytest.raises(ValueError, match="limit must be a finite cost > 0, got 0.0"):
        CostLagrangian(0.0, (1.0, 0.1, 0.0))


def test_the_state_round_trips_and_refuses_a_corrupt_entry():
    lag = CostLagrangian(limit=1.0, gains=(0.1, 0.01, 0.01), period=10)
    lag.observe([4.0, 2.0], frames=0)
    lag.observe([3.0], frames=10)
    other = CostLagrangian(limit=1.0, gains=(0.1, 0.01, 0.01), period=10)
    other.load_state_dict(lag.state_dict())
    assert other.state_dict() == lag.state_dict()
    assert lag.steps == 1 and lag.multiplier > 0
    bad_entries = (("multiplier", -1.0), ("integral", 1e9), ("recent", [math.inf]), ("frames", -2))
    for name, bad in bad_entries:
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


def test_a_run_steers_every_head_and_resumes_its_multiplier(tmp_path):
    """r+rc on the toy hand, limit 0.01, a period of 100 env steps and a 300-step warm-up: the
    multiplier stays 0 through the warm-up, then rises (every pressing episode costs > 0), and
    the actor's weights are 1 / (1 + lambda) and lambda / (1 + lambda); a resume restores it."""
    from gentlerl.training import Trainer
    from tests.helpers import tiny_config, toy_env

    gentle = dict(tolerance=0.5, multiplier="lagrangian", cost_limit=0.01, cost_period=100)
    gentle.update(cost_warmup_frames=300, cost_gains=(0.1, 0.1, 0.0))
    over = dict(variant="r+rc", gentleness=gentle, learner=dict(normalize_values=True))
    trainer = Trainer(tiny_config(tmp_path / "run", total_frames=900, **over), toy_env)
    assert trainer.learner.loss.normalize_values
    assert trainer.learner.loss.head_weights.tolist() == [1.0, 0.0]
    trainer.run()
    lag = trainer.rewards.lagrangian
    assert lag.steps == 6  # 400, 500, ..., 900: the multiples of 100 past the warm-up
    assert lag.cost > 0 and lag.multiplier > 0
    reward_side, cost_side = 1 / (1 + lag.multiplier), lag.multiplier / (1 + lag.multiplier)
    torch.testing.assert_close(
        trainer.learner.loss.head_weights, torch.tensor([reward_side, cost_side])
    )
    longer = tiny_config(tmp_path / "run", total_frames=1000, resume=True, **over)
    resumed = Trainer(longer, toy_env)
    resumed._resume()
    assert resumed.rewards.lagrangian.state_dict() == lag.state_dict()
    torch.testing.assert_close(resumed.learner.loss.head_weights, trainer.learner.loss.head_weights)


def test_the_lagrangian_and_a_derived_support_are_refused_up_front(tmp_path):
    from tests.helpers import tiny_config

    with pytest.raises(ValueError, match="weighs a cost head, which variant=r lacks"):
        tiny_config(tmp_path, variant="r", gentleness=dict(tolerance=1.0, multiplier="lagrangian"))
    with pytest.raises(ValueError, match="cost_limit=5.0 applies to gentleness.multiplier=lag"):
        tiny_config(tmp_path, variant="r+rc", gentleness=dict(cost_limit=5.0))
    with pytest.raises(ValueError, match="network.derive_support needs the task reward's per-s"):
        tiny_config(tmp_path, network=dict(derive_support=True))
    with pytest.raises(ValueError, match="network.v_max=100.0 sizes a hand-set support"):
        tiny_config(tmp_path, network=dict(derive_support=True, v_max=100.0))
