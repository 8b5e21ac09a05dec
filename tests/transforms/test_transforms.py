"""Gentleness transforms: hand-computed rewards, specs, gates and refusals (the TorchRL checklist
of env, batched envs, no env, Compose, replay buffer and clone cases: test_checklist.py)."""

import math
from functools import cache

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from tensordict import TensorDict
from torchrl.envs import ParallelEnv, RenameTransform, SerialEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.functional import gaussian_nll, information_gain, mixture_moments
from gentlerl.rewards import VARIANTS
from gentlerl.transforms import (
    DynamicsSurprise,
    ImpactPenalty,
    NonFiniteForceError,
    PenaltySurprise,
)
from tests.helpers import make_reward_transforms, pressing_rollout
from tests.toy_env import ToyHandEnv


def _press_batch():
    """Two transitions: 1 N at fingertip 0 (normal channel), then 2 N more at fingertip 1."""
    touch = torch.zeros(3, 5, 3)
    touch[1, 0, 0] = 1.0
    touch[2, 0, 0] = 1.0
    touch[2, 1, 0] = 2.0
    return TensorDict({keys.TOUCH: touch[:2], "next": {keys.TOUCH: touch[1:]}}, [2])


def test_impact_penalty_hand_computed():
    out = ImpactPenalty()(_press_batch())
    torch.testing.assert_close(
        out["next", keys.IMPACT][:, :2], torch.tensor([[1.0, 0.0], [0.0, 2.0]])
    )
    penalty = out["next", keys.PENALTY].squeeze(-1)
    assert penalty[0].item() == pytest.approx(-0.1192, abs=1e-4)
    assert penalty[1].item() == pytest.approx(-1.0, abs=1e-6)


def test_impact_penalty_custom_keys_and_bad_args():
    td = TensorDict({"force": torch.zeros(2, 3), "next": {"force": torch.ones(2, 3)}})
    out = ImpactPenalty((2.0, 2.0), in_keys=["force"], out_keys=["m", "rf"])(td)
    assert out["next", "m"].shape == (2,) and out["next", "m"].tolist() == [3.0, 3.0]
    with pytest.raises(ValueError, match="one force key"):
        ImpactPenalty(in_keys=["a", "b"])
    with pytest.raises(ValueError, match="lam"):
        ImpactPenalty((-1.0, 2.0))


@pytest.mark.parametrize("where", ["spec", "reset", "step", "batch"])
def test_a_missing_force_key_is_one_line_naming_it_and_the_keys_there(where):
    # The hand's force key is "touch"; an env that writes "force" needs in_keys=["force"].
    env = TransformedEnv(ToyHandEnv(), RenameTransform([keys.TOUCH], ["force"]))
    batch = env.rollout(2)
    penalty = ImpactPenalty()
    act = {
        "spec": lambda: env.append_transform(penalty).observation_spec,
        "reset": lambda: penalty._reset(batch[0], batch[0].exclude("next")),
        "step": lambda: penalty._step(batch[0], batch[0]["next"]),
        "batch": lambda: penalty(batch),
    }[where]
    with pytest.raises(ValueError) as err:
        act()
    message = str(err.value)
    assert "\n" not in message and "ImpactPenalty reads 'touch'" in message
    assert "'force'" in message and "'observation'" in message  # the keys the env has
    assert message.endswith("(set in_keys to the env's key)")


def test_impact_penalty_on_env_specs_reset_and_values():
    env = TransformedEnv(ToyHandEnv(), ImpactPenalty())
    check_env_specs(env)
    assert keys.PENALTY in env.reward_keys
    reset = env.reset()
    assert reset[keys.IMPACT].abs().sum() == 0  # no spurious impact at reset
    rollout = pressing_rollout(env)
    # From step 6 on, the force rises by 0.1 * 20 = 2 N (+ 0.2 N tangential) per step.
    impacts = rollout["next", keys.IMPACT][:, 1]
    assert impacts[:5].abs().max() < 1e-5
    torch.testing.assert_close(impacts[6:], torch.full((6,), 2.2), atol=1e-4, rtol=0)
    a = 1 / (1 + math.exp(2 * (2.2 - 2)))
    expected = -(1 - a) * 2.2
    torch.testing.assert_close(
        rollout["next", keys.PENALTY][6:, 0], torch.full((6,), expected), atol=1e-4, rtol=0
    )


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_variant_builds_and_specs_hold(variant):
    stack = make_reward_transforms(variant, reward_delay=0, hidden=16, ensemble_size=3)
    assert stack.reward_keys == list(VARIANTS[variant])
    expected_models = {
        "dynamics": keys.DYNAMICS_SURPRISE in stack.reward_keys,
        "penalty": keys.PENALTY_SURPRISE in stack.reward_keys,
        "icm": keys.ICM_REWARD in stack.reward_keys,
    }
    assert set(stack.losses) == {k for k, used in expected_models.items() if used}
    env = TransformedEnv(SerialEnv(1, ToyHandEnv), stack.transform.clone())
    check_env_specs(env)
    rollout = env.rollout(4)
    for key in stack.reward_keys:
        assert rollout["next", key].shape == (1, 4, 1)


def test_unknown_variant():
    with pytest.raises(ValueError, match=r"unknown variant 'r\+x'"):
        make_reward_transforms("r+x")


def test_dynamics_surprise_is_the_mixture_nll_and_waits_for_activation():
    stack = make_reward_transforms(
        "rs", reward_delay=10, hidden=16, ensemble_size=3, dynamics_surprise_scale=0.5
    )
    surprise = stack.transform[1]
    assert isinstance(surprise, DynamicsSurprise)
    batch = pressing_rollout(ToyHandEnv())
    assert stack.transform(batch.clone())["next", keys.DYNAMICS_SURPRISE].abs().sum() == 0
    stack.step(10)  # reward delay reached
    out = stack.transform(batch.clone())["next", keys.DYNAMICS_SURPRISE]
    # By hand: mixture moments of the target ensembles, NLL summed over the 63 dims.
    preds = stack.losses["dynamics"].predict_target(batch)
    expected = 0.0
    for key, (mean, var) in preds.items():
        mu, s2 = mixture_moments(mean, var)
        expected = expected + gaussian_nll(batch["next", key].flatten(1), mu, s2).sum(
            -1, keepdim=True
        )
    torch.testing.assert_close(out, 0.5 * expected)  # times dynamics_surprise_scale


def test_penalty_surprise_zero_without_impact_and_formula_with_it():
    stack = make_reward_transforms(
        "r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3, lam_prime=(2.0, 3.0)
    )
    stack.step(0)
    batch = pressing_rollout(ToyHandEnv())
    out = stack.transform(batch)
    penalty = out["next", keys.PENALTY]
    rsp = out["next", keys.PENALTY_SURPRISE]
    assert (rsp[penalty == 0] == 0).all()
    hit = penalty < 0
    assert hit[6:].all()
    mean, var = stack.losses["penalty"].predict_target(batch)
    mu, s2 = mixture_moments(mean, var)
    nll = gaussian_nll(penalty, mu, s2)
    a = torch.sigmoid(2.0 * (3.0 + penalty))  # acceptability of |r^f| with lambda' = [2, 3]
    torch.testing.assert_close(rsp[hit], (a * (nll - penalty))[hit])
    assert isinstance(stack.transform[1], PenaltySurprise)


def test_penalty_surprise_scale_shrinks_the_nll_not_the_refund():
    """surprise_scale s: r^sp = a'(s nll - r^f), so r^f + r^sp = a' s nll + (1 - a') r^f (eq. 7).

    With s = 0 the sum is (1 - a') r^f: the refund of the acceptable part of the penalty stays,
    only the curiosity is gone (scaling the whole reward would give back the full penalty).
    """
    out = {}
    for scale in (1.0, 0.25, 0.0):
        stack = make_reward_transforms(
            "r+rf+rsp",
            reward_delay=0,
            hidden=16,
            ensemble_size=3,
            lam_prime=(2.0, 3.0),
            surprise_scale=scale,
        )
        stack.step(0)
        batch = pressing_rollout(ToyHandEnv())
        out[scale] = stack.transform(batch)
    penalty = out[1.0]["next", keys.PENALTY]
    hit = penalty < 0
    a = torch.sigmoid(2.0 * (3.0 + penalty))
    nll = out[1.0]["next", keys.PENALTY_SURPRISE] / a + penalty  # invert eq. 8 at s = 1
    for scale in (0.25, 0.0):
        rsp = out[scale]["next", keys.PENALTY_SURPRISE]
        torch.testing.assert_close(rsp[hit], (a * (scale * nll + -penalty))[hit])
    total = penalty + out[0.0]["next", keys.PENALTY_SURPRISE]
    torch.testing.assert_close(total[hit], ((1 - a) * penalty)[hit])


def test_step_copies_targets_at_their_periods():
    stack = make_reward_transforms("r+rf+rsp", reward_delay=5, penalty_target_period=3, hidden=16)
    loss = stack.losses["penalty"]
    with torch.no_grad():
        loss.model_params["ensemble", "head", "bias"].add_(1.0)
    target = loss.target_model_params["ensemble", "head", "bias"]
    stack.step(1)
    stack.step(2)
    assert not torch.allclose(target, loss.model_params["ensemble", "head", "bias"])
    assert not stack.intrinsic_on
    stack.step(3)  # the 3rd update copies
    torch.testing.assert_close(target, loss.model_params["ensemble", "head", "bias"].data)
    with torch.no_grad():
        loss.model_params["ensemble", "head", "bias"].add_(1.0)
    stack.step(4)
    stack.step(5)
    assert not torch.allclose(target, loss.model_params["ensemble", "head", "bias"])
    assert stack.intrinsic_on  # reward_delay = 5 reached
    stack.step(6)  # the 6th update copies again
    torch.testing.assert_close(target, loss.model_params["ensemble", "head", "bias"].data)


def test_state_dict_round_trip():
    a = make_reward_transforms("r+rf+rs", reward_delay=0, hidden=16, seed=1)
    b = make_reward_transforms("r+rf+rs", reward_delay=0, hidden=16, seed=2)
    a.step(0)
    b.load_state_dict(a.state_dict())
    assert b.intrinsic_on
    batch = pressing_rollout(ToyHandEnv())
    torch.testing.assert_close(
        a.transform(batch.clone())["next", keys.DYNAMICS_SURPRISE],
        b.transform(batch.clone())["next", keys.DYNAMICS_SURPRISE],
    )


@pytest.mark.parametrize("variant", ["r+rf+rsp", "r+rf+rs", "r+icm"])
def test_transformed_hand_env_passes_check_env_specs(variant, hand_env):
    stack = make_reward_transforms(variant, reward_delay=0, hidden=16)
    stack.step(0)
    env = TransformedEnv(hand_env("touch", seed=0), stack.transform)
    check_env_specs(env)
    rollout = env.rollout(5)
    assert rollout["next", keys.IMPACT].shape == (5, 5)
    assert rollout["next", stack.reward_keys[-1]].shape == (5, 1)
    assert torch.isfinite(rollout["next", stack.reward_keys[-1]]).all()


def test_impact_penalty_on_a_parallel_hand_env():
    from functools import partial

    from gentlerl.envs import make_env

    env = TransformedEnv(
        ParallelEnv(2, partial(make_env, "touch", seed=0), mp_start_method="fork"), ImpactPenalty()
    )
    try:
        check_env_specs(env)
        rollout = env.rollout(6)
        assert rollout["next", keys.PENALTY].shape == (2, 6, 1)
        assert (rollout["next", keys.PENALTY] <= 0).all()
    finally:
        env.close()


def test_penalty_surprise_nll_floor_keeps_the_surprise_a_bonus():
    # A well-predicted penalty has a negative NLL; eq. 8 then gives r^f + r^sp = a' nll + (1 - a') r^f
    # below r^f. With nll_floor=0 the well-predicted case costs only (1 - a') r^f.
    stack = make_reward_transforms("r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3)
    stack.step(0)
    surprise = stack.transform[1]
    batch = pressing_rollout(ToyHandEnv())
    stack.transform[0](batch)  # write the penalty first
    mean, var = stack.losses["penalty"].predict_target(batch)
    mu, s2 = mixture_moments(mean, var)
    penalty = batch["next", keys.PENALTY]
    # Make the target model "accurate": evaluate eq. 8 at nll = -3 by hand vs the floored version.
    nll = torch.full_like(penalty, -3.0)
    from gentlerl.functional import penalty_surprise

    raw = penalty_surprise(penalty, nll, 2.0, 2.0)
    floored = penalty_surprise(penalty, nll.clamp_min(0.0), 2.0, 2.0)
    hit = penalty < 0
    assert (raw[hit] < floored[hit]).all() and (floored[hit] >= 0).all()
    surprise.nll_floor = 0.0
    out = surprise(batch.clone())["next", keys.PENALTY_SURPRISE]
    expected = penalty_surprise(penalty, gaussian_nll(penalty, mu, s2).clamp_min(0.0), 2.0, 2.0)
    torch.testing.assert_close(out, expected)


def test_penalty_surprise_sources_add_up_to_the_paid_reward():
    # curiosity a' s nll + refund -a' r^f is r^sp on each contact step (scale 0.5, and a floor of
    # 5 nats that binds: these NLLs are ~2); the NLL's two terms are gaussian_nll's, the variance
    # splits as in eq. 5, and before the switch both parts are 0 as the reward is.
    stack = make_reward_transforms(
        "r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3, surprise_scale=0.5,
        surprise_nll_floor=5.0,
    )  # fmt: skip
    surprise = stack.transform[1]
    closed = surprise.sources(stack.transform(pressing_rollout(ToyHandEnv())))
    assert (closed["curiosity"] == 0).all() and (closed["refund"] == 0).all()
    stack.step(0)
    batch = stack.transform(pressing_rollout(ToyHandEnv()))
    parts = surprise.sources(batch)
    hit = parts["penalty"] < 0
    assert hit.any() and (parts["spread"] + parts["error"] < 5.0)[hit].all()  # the floor binds
    torch.testing.assert_close(parts["curiosity"][hit], (parts["a_prime"] * 0.5 * 5.0)[hit])
    rsp = batch["next", keys.PENALTY_SURPRISE]
    torch.testing.assert_close((parts["curiosity"] + parts["refund"])[hit], rsp[hit])
    mean, var = stack.losses["penalty"].predict_target(batch)
    mu, s2 = mixture_moments(mean, var)
    nll = gaussian_nll(batch["next", keys.PENALTY], mu, s2)
    torch.testing.assert_close(parts["spread"] + parts["error"], nll)
    torch.testing.assert_close(parts["aleatoric"] + parts["epistemic"], s2)
    with pytest.raises(ValueError, match="penalty"):
        surprise.sources(batch.exclude(("next", keys.PENALTY)))


def test_penalty_surprise_information_gain_reads_the_members_disagreement():
    # kind="information_gain": r^sp = a'(s I - r^f), I = 1/2 log(sigma*^2 / mean sigma_i^2);
    # its sources say the same, and the NLL diagnostics stay those of the mixture.
    stack = make_reward_transforms(
        "r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3, lam_prime=(2.0, 3.0),
        surprise_scale=0.5, surprise_kind="information_gain",
    )  # fmt: skip
    stack.step(0)
    batch = stack.transform(pressing_rollout(ToyHandEnv()))
    penalty = batch["next", keys.PENALTY]
    hit = penalty < 0
    mean, var = stack.losses["penalty"].predict_target(batch)
    gain = information_gain(mean, var)
    a = torch.sigmoid(2.0 * (3.0 + penalty))
    rsp = batch["next", keys.PENALTY_SURPRISE]
    torch.testing.assert_close(rsp[hit], (a * (0.5 * gain - penalty))[hit])
    assert (rsp[~hit] == 0).all()
    parts = stack.transform[1].sources(batch)
    torch.testing.assert_close((parts["curiosity"] + parts["refund"])[hit], rsp[hit])
    with pytest.raises(ValueError, match="kind must be one of"):
        PenaltySurprise(stack.losses["penalty"].model, stack.losses["penalty"].target_model_params,
                        kind="entropy")  # fmt: skip


def test_penalty_surprise_reads_the_model_on_penalty_rows_only(monkeypatch):
    # Eq. 8 on a [4, 6] batch where some steps press: the values are the equation's on every row
    # (computed here on the whole batch), and the model saw the pressing rows only.
    stack = make_reward_transforms("r+rf+rsp", reward_delay=0, hidden=16, ensemble_size=3)
    stack.step(0)
    impact, surprise = stack.transform[0], stack.transform[1]
    touch = torch.rand(24, 5, 3) * 2.0
    touch[::2] = 0.0  # no force at the even steps
    batch = impact(_transitions(torch.zeros_like(touch), touch)).reshape(4, 6)
    penalty = batch["next", keys.PENALTY]
    assert 0 < int((penalty < 0).sum()) < 24
    seen = []
    predict = surprise.predict
    monkeypatch.setattr(
        surprise, "predict", lambda td, params=None: seen.append(td.numel()) or predict(td, params)
    )
    rsp = surprise(batch)["next", keys.PENALTY_SURPRISE]
    assert rsp.shape == (4, 6, 1) and seen == [int((penalty < 0).sum())]
    mean, var = stack.losses["penalty"].predict_target(batch)
    mu, s2 = mixture_moments(mean, var)
    a = torch.sigmoid(2.0 * (2.0 + penalty))  # acceptability of |r^f|, lambda' = [2, 2]
    expected = torch.where(penalty < 0, a * (gaussian_nll(penalty, mu, s2) - penalty), 0.0)
    torch.testing.assert_close(rsp, expected)
    seen.clear()
    quiet = impact(_transitions(torch.zeros_like(touch), torch.zeros_like(touch)))
    assert (surprise(quiet)["next", keys.PENALTY_SURPRISE] == 0).all() and seen == []


def test_icm_reward_is_half_eta_times_the_squared_feature_error():
    stack = make_reward_transforms("r+icm", reward_delay=3, icm_eta=3.0)
    batch = pressing_rollout(ToyHandEnv())
    assert stack.transform(batch.clone())["next", keys.ICM_REWARD].abs().sum() == 0  # delay
    stack.step(3)
    out = stack.transform(batch.clone())["next", keys.ICM_REWARD]
    _, predicted_next, next_phi = stack.losses["icm"].predict(batch)
    expected = 1.5 * (predicted_next - next_phi).pow(2).sum(-1, keepdim=True)
    torch.testing.assert_close(out, expected.detach())
    assert (out > 0).all()


@cache
def _active_stack(variant):
    stack = make_reward_transforms(variant, reward_delay=0, hidden=16, ensemble_size=2)
    stack.step(0)  # the gate is open: the models' rewards count
    return stack


def _transitions(touch, next_touch):
    n = touch.shape[0]
    gen = torch.Generator().manual_seed(0)
    pos, vel, next_pos, next_vel = (torch.randn(n, 24, generator=gen) for _ in range(4))

    def obs(p, v, t):
        return {
            keys.JOINT_POS: p,
            keys.JOINT_VEL: v,
            keys.TOUCH: t,
            keys.OBSERVATION: torch.cat([p, v, t.flatten(1)], -1),
        }

    td = {**obs(pos, vel, touch), keys.ACTION: torch.rand(n, 20, generator=gen) * 2 - 1}
    return TensorDict({**td, "next": obs(next_pos, next_vel, next_touch)}, [n])


@pytest.mark.parametrize("variant", ["r+rf+rs", "r+rf+rsp", "r+icm"])
@settings(max_examples=25, deadline=None)
@given(
    row=st.integers(0, 3),
    site=st.integers(0, 4),
    channel=st.integers(0, 2),
    bad=st.sampled_from([float("nan"), float("inf"), float("-inf")]),
    in_next=st.booleans(),
)
def test_a_non_finite_force_is_refused_naming_where(variant, row, site, channel, bad, in_next):
    """A NaN / inf force at s_t or s_{t+1} is an error naming the key, the step and the index
    (it would make every reward of that transition and the models non-finite)."""
    stack = _active_stack(variant)
    touch, next_touch = torch.rand(4, 5, 3) * 3, torch.rand(4, 5, 3) * 3
    (next_touch if in_next else touch)[row, site, channel] = bad
    step = r"s_t\+1" if in_next else "s_t"
    with pytest.raises(NonFiniteForceError, match=rf"\({bad}\) at {step}, index \[{row}\], "
                       rf"site {site}, channel {channel}"):  # fmt: skip
        stack.transform(_transitions(touch, next_touch))


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_impact_penalty_refuses_a_non_finite_force_naming_the_key_and_step(bad):
    """The finding: NaN / inf forces through the drop-in gave NaN rewards with no error."""
    force = torch.zeros(4, 5, 3)
    nxt = force.clone()
    nxt[2, 1, 0] = bad
    td = TensorDict({"touch": force, "next": {"touch": nxt}}, [4])
    with pytest.raises(ValueError, match=rf"'touch' holds a non-finite force \({bad}\) at "
                       r"s_t\+1, index \[2\], site 1, channel 0"):  # fmt: skip
        ImpactPenalty()(td)


def test_impact_penalty_refuses_an_integer_force():
    td = TensorDict({"touch": torch.zeros(5, 3, dtype=torch.int64),
                     "next": {"touch": torch.ones(5, 3, dtype=torch.int64)}})  # fmt: skip
    with pytest.raises(ValueError, match="'touch' must be a floating-point force, got torch.int64"):
        ImpactPenalty()(td)


def test_a_deep_copy_shares_the_model_and_the_gate_and_an_unpickled_one_refuses():
    """The finding: copy.deepcopy / pickle of rewards.transform gave a copy with a model of its
    own whose gate never opened (r^sp 0 while the original paid 2.19), silently."""
    import copy
    import pickle

    stack = make_reward_transforms("r+rf+rsp", reward_delay=5, hidden=16, ensemble_size=2)
    copied = copy.deepcopy(stack.transform)
    pickled = pickle.loads(pickle.dumps(stack.transform))
    stack.step(5)  # the gate opens: in the deep copy too
    surprise = [t for t in copied if isinstance(t, PenaltySurprise)][0]
    original = [t for t in stack.transform if isinstance(t, PenaltySurprise)][0]
    assert bool(surprise.active) and surprise.model is original.model
    batch = _transitions(torch.rand(4, 5, 3), torch.rand(4, 5, 3) + 4)
    torch.testing.assert_close(
        copied(batch.clone())["next", keys.PENALTY_SURPRISE],
        stack.transform(batch.clone())["next", keys.PENALTY_SURPRISE],
    )
    with pytest.raises(RuntimeError, match="PenaltySurprise was unpickled: its model is a copy"):
        pickled(batch.clone())


def test_impact_penalty_refuses_forces_whose_penalty_overflows():
    """The finding: 3e38 N forces (finite) gave NaN rewards and a NaN model loss."""
    nxt = torch.zeros(5, 3)
    nxt[:, 0] = 3e38
    td = TensorDict({"touch": torch.zeros(5, 3), "next": {"touch": nxt}})
    with pytest.raises(NonFiniteForceError, match=r"forces up to 3e\+38 overflow the penalty"):
        ImpactPenalty()(td)
