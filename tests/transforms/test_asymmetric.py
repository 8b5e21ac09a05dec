"""Every transform of gentlerl.transforms at asymmetric, non-default settings, against numbers
worked out here by hand (the equations written out with ``math``, never the library's helpers).

At the paper's ``lam = (2, 2)`` swapping lambda_1 and lambda_2 changes nothing, and at
``unit = 1`` dividing or multiplying by the unit is the same: here every lambda pair is unequal,
the force unit is 1.5, every batch has several sites and channels, and the model-reading
transforms read small stand-in models whose predictions are written out (their target
parameters differ from the module's own, so reading the wrong ones shows).
"""

import math

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torch import nn

from gentlerl.transforms import (
    DynamicsSurprise,
    ForcePenalty,
    ICMReward,
    ImpactPenalty,
    PenaltySurprise,
    TorquePenalty,
    TouchSensorMap,
)


def _a(x: float, lam1: float, lam2: float) -> float:
    """Eq. 3 as the paper writes it: 1 / (1 + exp(lambda_1 (x - lambda_2)))."""
    return 1.0 / (1.0 + math.exp(lam1 * (x - lam2)))


def _cost(m: float, lam1: float, lam2: float) -> float:
    """One site's term of eq. 4: (1 - a(m)) m."""
    return (1.0 - _a(m, lam1, lam2)) * m


def _nll(x: float, mean: float, var: float) -> float:
    """-log N(x | mean, var)."""
    return 0.5 * (math.log(2 * math.pi * var) + (x - mean) ** 2 / var)


# -- ImpactPenalty (eqs. 1, 3, 4) -------------------------------------------------------------


def _touch_batch():
    """Two transitions, 3 sites x 2 channels; impacts (N) [[3, 0, 0.5], [0, 4.5, 0]]."""
    touch = torch.tensor(
        [[[1.0, 0.0], [2.0, 2.0], [0.0, 0.0]], [[4.0, 0.0], [2.0, 2.0], [0.25, 0.25]]]
    )
    next_touch = torch.tensor(
        # site 0: +3 on channel 0; site 2: +0.25 on each channel; site 1 falls (no impact)
        [[[4.0, 0.0], [1.0, 1.0], [0.25, 0.25]],
         # site 1: +1.5 and +3; site 0 and 2 fall
         [[3.0, 0.0], [3.5, 5.0], [0.0, 0.0]]]
    )  # fmt: skip
    return TensorDict({"touch": touch, "next": {"touch": next_touch}}, [2])


def test_impact_penalty_at_lambda_1_4_charges_a_3n_impact_0_807():
    # One 3 N impact at lam = (1, 4), unit 1: -(1 - sigmoid(1 * (4 - 3))) * 3 = -0.807.
    td = TensorDict(
        {"touch": torch.zeros(3, 2), "next": {"touch": torch.tensor([[3.0, 0], [0, 0], [0, 0]])}}
    )
    out = ImpactPenalty((1.0, 4.0))(td)
    assert out["next", "penalty"].shape == (1,)
    assert out["next", "penalty"].item() == pytest.approx(-0.8068, abs=1e-4)
    assert out["next", "penalty"].item() == pytest.approx(-_cost(3.0, 1.0, 4.0), rel=1e-6)


def test_impact_penalty_over_sites_and_channels_with_a_force_unit():
    # lam = (1, 4), unit 1.5: impacts are written in N, the penalty reads m / 1.5.
    out = ImpactPenalty((1.0, 4.0), unit=1.5)(_touch_batch())
    impacts = [[3.0, 0.0, 0.5], [0.0, 4.5, 0.0]]
    torch.testing.assert_close(out["next", "impact"], torch.tensor(impacts))
    expected = [[-sum(_cost(m / 1.5, 1.0, 4.0) for m in row)] for row in impacts]
    torch.testing.assert_close(out["next", "penalty"], torch.tensor(expected))
    # 4.5 N in units of 1.5 N is 3 units: -0.807 again.
    assert out["next", "penalty"][1].item() == pytest.approx(-0.8068, abs=1e-4)


def test_impact_penalty_in_newtons_at_the_mirror_lambdas_is_another_penalty():
    out = ImpactPenalty((4.0, 1.0))(_touch_batch())
    expected = [
        [-(_cost(3.0, 4.0, 1.0) + _cost(0.5, 4.0, 1.0))],
        [-_cost(4.5, 4.0, 1.0)],
    ]
    torch.testing.assert_close(out["next", "penalty"], torch.tensor(expected))


# -- ForcePenalty and TorquePenalty ------------------------------------------------------------


def test_force_penalty_at_lambda_half_6_reads_each_sites_total_after_the_step():
    # next touch totals per site [[4, 2, 0.5], [3, 8.5, 0]]; the step's start does not matter.
    out = ForcePenalty((0.5, 6.0))(_touch_batch())
    totals = [[4.0, 2.0, 0.5], [3.0, 8.5, 0.0]]
    expected = [[-sum(_cost(f, 0.5, 6.0) for f in row)] for row in totals]
    torch.testing.assert_close(out["next", "force_penalty"], torch.tensor(expected))


def test_torque_penalty_at_lambda_3_half_reads_effort_magnitudes():
    torque = torch.tensor([[-1.0, 0.2, 0.8], [2.0, 0.0, -0.5]])
    td = TensorDict({"actuator_force": torch.zeros(2, 3), "next": {"actuator_force": torque}}, [2])
    out = TorquePenalty((3.0, 0.5))(td)
    expected = [[-sum(_cost(abs(t), 3.0, 0.5) for t in row)] for row in torque.tolist()]
    torch.testing.assert_close(out["next", "torque_penalty"], torch.tensor(expected))
    # 1 N m at (3, 0.5): (1 - 1 / (1 + e^1.5)) = 0.8176 of it is charged.
    assert _cost(1.0, 3.0, 0.5) == pytest.approx(0.8176, abs=1e-4)


# -- the model-reading transforms, on stand-in models -----------------------------------------


class _PenaltyStub(nn.Module):
    """Member m predicts r^f ~ N(w_m + obs_0, v_m) (``[M, N, 1]``), as PenaltyModel.predict."""

    obs_key, action_key = "observation", "action"

    def __init__(self):
        super().__init__()
        self.w = nn.Parameter(torch.zeros(2))
        self.v = nn.Parameter(torch.ones(2))

    def predict(self, td):
        obs = td.get(self.obs_key)[..., :1]  # [N, 1]
        mean = self.w[:, None, None] + obs.unsqueeze(0)
        return mean, self.v[:, None, None].expand_as(mean)


def _target(model, **values):
    """The parameters a transform reads: a copy of ``model``'s set to ``values``."""
    params = TensorDict.from_module(model).clone()
    for name, value in values.items():
        params[name] = torch.tensor(value)
    return params


def _surprise_batch():
    """Three steps: r^f = -3 (obs_0 = 0), 0 (obs_0 = 1), -0.5 (obs_0 = 0.25)."""
    obs = torch.tensor([[0.0, 9.0], [1.0, 9.0], [0.25, 9.0]])
    return TensorDict(
        {
            "observation": obs,
            "action": torch.zeros(3, 1),
            "next": {"penalty": torch.tensor([[-3.0], [0.0], [-0.5]])},
        },
        [3],
    )


def _surprise(**kwargs):
    model = _PenaltyStub()  # its own parameters (0, 1) are not the ones read
    transform = PenaltySurprise(model, _target(model, w=[-2.5, -3.5], v=[0.5, 1.5]), **kwargs)
    transform.active.fill_(True)
    return transform


#: The target members' mixture at the two contact rows: means (-2.5, -3.5) + obs_0, variances
#: (0.5, 1.5): mu* = -3 + obs_0, sigma*^2 = 1 (mean variance) + 0.25 (spread) = 1.25.
NLL_0 = _nll(-3.0, -3.0, 1.25)  # obs_0 = 0: the mixture's mean is the penalty
NLL_2 = _nll(-0.5, -2.75, 1.25)  # obs_0 = 0.25


def test_penalty_surprise_at_lambda_prime_1_4_with_half_the_nll():
    # r^sp = a'(s nll - r^f), a' = a(|r^f|) at lam' = (1, 4), s = 0.5; 0 where r^f = 0.
    out = _surprise(lam_prime=(1.0, 4.0), scale=0.5)(_surprise_batch())["next", "penalty_surprise"]
    expected = [
        _a(3.0, 1.0, 4.0) * (0.5 * NLL_0 + 3.0),
        0.0,
        _a(0.5, 1.0, 4.0) * (0.5 * NLL_2 + 0.5),
    ]
    torch.testing.assert_close(out, torch.tensor(expected).unsqueeze(-1))
    # numbers: a(3) = 0.7311, NLL_0 = 1/2 log(2.5 pi) = 1.0301 -> 0.7311 * 3.5150 = 2.5698
    assert out[0].item() == pytest.approx(2.5698, abs=1e-3)


def test_penalty_surprise_gate_closed_pays_nothing():
    transform = _surprise(lam_prime=(1.0, 4.0))
    transform.active.fill_(False)
    assert (transform(_surprise_batch())["next", "penalty_surprise"] == 0).all()


def test_penalty_surprise_nll_floor_binds_where_the_nll_is_below_it():
    # floor 2: NLL_0 = 1.03 becomes 2, NLL_2 = 3.06 stays.
    assert NLL_0 < 2.0 < NLL_2
    out = _surprise(lam_prime=(1.0, 4.0), nll_floor=2.0)(_surprise_batch())
    expected = [_a(3.0, 1, 4) * (2.0 + 3.0), 0.0, _a(0.5, 1, 4) * (NLL_2 + 0.5)]
    torch.testing.assert_close(
        out["next", "penalty_surprise"], torch.tensor(expected).unsqueeze(-1)
    )


def test_penalty_surprise_information_gain_and_the_running_normalisation():
    # I = 1/2 log(sigma*^2 / mean variance) = 1/2 log(1.25 / 1) on both contact rows; with
    # normalize the first batch's scale is the mean |I| itself, so the curiosity becomes 1.
    gain = 0.5 * math.log(1.25)
    out = _surprise(lam_prime=(1.0, 4.0), kind="information_gain", scale=2.0)(_surprise_batch())
    expected = [_a(3.0, 1, 4) * (2.0 * gain + 3.0), 0.0, _a(0.5, 1, 4) * (2.0 * gain + 0.5)]
    torch.testing.assert_close(
        out["next", "penalty_surprise"], torch.tensor(expected).unsqueeze(-1)
    )
    transform = _surprise(lam_prime=(1.0, 4.0), normalize=True)
    out = transform(_surprise_batch())["next", "penalty_surprise"]
    scale = (abs(NLL_0) + abs(NLL_2)) / 2
    expected = [_a(3.0, 1, 4) * (NLL_0 / scale + 3.0), 0.0, _a(0.5, 1, 4) * (NLL_2 / scale + 0.5)]
    torch.testing.assert_close(out, torch.tensor(expected).unsqueeze(-1))
    assert transform.curiosity_scale == (pytest.approx(scale), 1)


class _DynamicsStub(nn.Module):
    """Member m predicts each next feature ~ N(feature_t + d_m, v_m), as DynamicsModel.predict."""

    obs_key, action_key = "observation", "action"
    feature_shapes = {"touch": (2, 2), "joint_pos": (3,)}

    def __init__(self):
        super().__init__()
        self.d = nn.Parameter(torch.zeros(2))
        self.v = nn.Parameter(torch.ones(2))

    def predict(self, td):
        out = {}
        for key, shape in self.feature_shapes.items():
            now = td.get(key).flatten(-len(shape)).unsqueeze(0)  # [1, B, D]
            mean = now + self.d[:, None, None]
            out[key] = (mean, self.v[:, None, None].expand_as(mean))
        return out


def test_dynamics_surprise_sums_the_mixture_nll_over_every_feature_dimension():
    # target members: d = (1, -0.5), v = (0.5, 2): mixture mean feature_t + 0.25, variance
    # 1.25 + spread 0.5625 = 1.8125; r^s = 0.25 * sum over the 4 + 3 dims of the NLL.
    model = _DynamicsStub()
    transform = DynamicsSurprise(model, _target(model, d=[1.0, -0.5], v=[0.5, 2.0]), scale=0.25)
    transform.active.fill_(True)
    touch = torch.tensor([[[0.0, 1.0], [2.0, 0.0]]])
    next_touch = torch.tensor([[[0.5, 1.0], [0.0, 3.0]]])
    pos, next_pos = torch.tensor([[0.0, 1.0, -1.0]]), torch.tensor([[0.25, 3.0, -1.0]])
    td = TensorDict(
        {
            "observation": torch.zeros(1, 2),
            "action": torch.zeros(1, 1),
            "touch": touch,
            "joint_pos": pos,
            "next": {"touch": next_touch, "joint_pos": next_pos},
        },
        [1],
    )
    out = transform(td)["next", "dynamics_surprise"]
    pairs = list(zip(touch.flatten().tolist(), next_touch.flatten().tolist(), strict=True))
    pairs += list(zip(pos.flatten().tolist(), next_pos.flatten().tolist(), strict=True))
    expected = 0.25 * sum(_nll(nxt, now + 0.25, 1.8125) for now, nxt in pairs)
    assert out.shape == (1, 1) and out.item() == pytest.approx(expected, rel=1e-5)


class _ICMStub(nn.Module):
    """phi(s) = s; the forward model predicts phi(s') = k * s + action (ICMModel.predict's tuple)."""

    obs_key, action_key = "observation", "action"

    def __init__(self):
        super().__init__()
        self.k = nn.Parameter(torch.ones(()))

    def predict(self, td):
        obs, action = td.get(self.obs_key), td.get(self.action_key)
        next_obs = td.get(("next", self.obs_key))
        return None, self.k * obs + action, next_obs


def test_icm_reward_is_half_eta_times_the_squared_feature_error():
    # eta = 3, k = 2: r = 1.5 * sum_d (2 s_d + a_d - s'_d)^2 per step.
    model = _ICMStub()
    transform = ICMReward(model, _target(model, k=2.0), eta=3.0)
    transform.active.fill_(True)
    obs = torch.tensor([[1.0, -1.0], [0.5, 0.0]])
    action = torch.tensor([[0.0, 1.0], [-1.0, 0.5]])
    next_obs = torch.tensor([[1.0, 0.0], [0.0, 2.0]])
    td = TensorDict({"observation": obs, "action": action, "next": {"observation": next_obs}}, [2])
    out = transform(td)["next", "icm_reward"]
    # step 0: (2 - 1)^2 + (-2 + 1 - 0)^2 = 2 -> 3.0; step 1: (1 - 1 - 0)^2 + (0.5 - 2)^2 = 2.25
    torch.testing.assert_close(out, torch.tensor([[3.0], [1.5 * 2.25]]))


# -- TouchSensorMap ------------------------------------------------------------------------


def test_touch_sensor_map_recovers_a_different_linear_sensor_per_site_and_channel():
    # raw = k f + b per (site, channel), 2 sites x 2 channels, all slopes and offsets unequal.
    k = np.array([[2.0, 5.0], [0.5, 10.0]])
    b = np.array([[100.0, 0.0], [-3.0, 7.0]])
    force = np.linspace(0.0, 4.0, 64)[:, None, None] * np.ones((1, 2, 2))
    sensor_map = TouchSensorMap(n_sites=2, n_channels=2, n_knots=8)
    errors = sensor_map.fit(k * force + b, force)
    assert errors["max_abs_error_N"] < 1e-4
    query = np.array([[[1.0, 3.0], [0.25, 2.0]]])  # N, inside the fitted range
    got = sensor_map.forward_map(k * query + b)
    torch.testing.assert_close(got, torch.from_numpy(query), atol=1e-4, rtol=0)
    # past the range the last slope goes on (6 N), below it the map is flat at 0 N
    torch.testing.assert_close(
        sensor_map.forward_map(k * 6.0 + b), torch.full((2, 2), 6.0, dtype=torch.float64),
        atol=1e-4, rtol=0,
    )  # fmt: skip
    below = sensor_map.forward_map(k * -1.0 + b)
    torch.testing.assert_close(below, torch.zeros(2, 2, dtype=torch.float64), atol=1e-5, rtol=0)
    # the zero level is b; drift of +0.3 raw units is the tare, and removed
    offset = sensor_map.tare(b + 0.3)
    torch.testing.assert_close(offset, torch.full((2, 2), 0.3, dtype=torch.float64))
    shifted = sensor_map.forward_map(k * query + b + 0.3, offset)
    torch.testing.assert_close(shifted, torch.from_numpy(query), atol=1e-4, rtol=0)
    # the inverse is raw = k f + b; as a transform it writes float32 forces
    back = sensor_map.inverse(torch.from_numpy(query))
    torch.testing.assert_close(back, torch.from_numpy(k * query + b), atol=1e-4, rtol=0)
    td = TensorDict({"tactile": torch.from_numpy(k * query + b).float()}, [1])
    out = sensor_map(td)["tactile_force"]
    assert out.dtype == torch.float32
    torch.testing.assert_close(out, torch.from_numpy(query).float(), atol=1e-4, rtol=0)


def test_icm_reward_default_eta_is_1_so_half_the_squared_error():
    model = _ICMStub()
    transform = ICMReward(model, _target(model, k=2.0))
    transform.active.fill_(True)
    td = TensorDict(
        {
            "observation": torch.tensor([[1.0, -1.0]]),
            "action": torch.tensor([[0.0, 1.0]]),
            "next": {"observation": torch.tensor([[1.0, 0.0]])},
        },
        [1],
    )
    # squared error 2 (as above) times eta / 2 = 0.5
    torch.testing.assert_close(transform(td)["next", "icm_reward"], torch.tensor([[1.0]]))


@pytest.mark.parametrize("unit", [0.0, -1.5, float("inf"), float("nan")])
def test_impact_penalty_refuses_a_force_unit_that_is_not_a_finite_positive_force(unit):
    with pytest.raises(ValueError, match=r"^ImpactPenalty: unit must be a finite force > 0, got"):
        ImpactPenalty((1.0, 4.0), unit=unit)
