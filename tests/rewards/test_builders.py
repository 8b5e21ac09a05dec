"""The components' builders (``gentlerl.rewards.variants``) as ``IntrinsicRewards`` builds them:
each model's sizes, keys and seed, the parameters its transform reads, its scale, its target
updater's period, and the wear penalties' keys, checked against models built here by hand."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.models import DynamicsModel, ICMModel, PenaltyModel
from gentlerl.objectives import ICMLoss
from gentlerl.rewards import IntrinsicRewards
from gentlerl.transforms import (
    DynamicsSurprise,
    ForcePenalty,
    ICMReward,
    PenaltySurprise,
    TorquePenalty,
)

OBS, ACT = 4, 2


def _transition(batch: int = 6, seed: int = 0, obs_key: str = "state") -> TensorDict:
    g = torch.Generator().manual_seed(seed)
    touch = torch.rand(batch, 2, 2, generator=g)
    return TensorDict(
        {
            obs_key: torch.randn(batch, OBS, generator=g),
            keys.ACTION: torch.rand(batch, ACT, generator=g) * 2 - 1,
            "force": touch,
            "next": {
                obs_key: torch.randn(batch, OBS, generator=g),
                "force": touch + torch.rand(batch, 2, 2, generator=g),
            },
        },
        [batch],
    )


def _assert_same_parameters(got: TensorDict, expected: TensorDict) -> None:
    assert set(got.keys(True, True)) == set(expected.keys(True, True))
    for key, value in expected.items(True, True):
        torch.testing.assert_close(got[key].data, value.data, rtol=0, atol=0, msg=str(key))


def test_the_icm_model_is_built_under_seed_plus_2_with_the_envs_sizes_and_keys():
    settings = GentlenessConfig(model_batch_size=4, reward_delay=0)
    before = torch.random.get_rng_state()
    rewards = IntrinsicRewards(
        "r+icm", settings, obs_dim=OBS, action_dim=ACT, feature_shapes={}, seed=3,
        obs_key="state", force_key="force",
    )  # fmt: skip
    assert torch.equal(torch.random.get_rng_state(), before)  # the global stream is untouched
    loss = rewards.losses["icm"]
    assert isinstance(loss, ICMLoss)
    torch.manual_seed(3 + 2)
    expected = ICMModel(OBS, ACT, obs_key="state")
    _assert_same_parameters(loss.model_params, TensorDict.from_module(expected))
    assert (loss.model.obs_key, loss.model.action_key) == ("state", keys.ACTION)


def test_the_icm_reward_is_eta_over_2_times_the_forward_error_of_the_online_model():
    """r^i = eta / 2 ||f(phi(s), a) - phi(s')||^2 (Pathak et al. 2017), read from the loss's
    online parameters: a gradient step changes it at once (ICM has no target copy)."""
    settings = GentlenessConfig(icm_eta=0.6, model_batch_size=4, reward_delay=0)
    rewards = IntrinsicRewards(
        "r+icm", settings, obs_dim=OBS, action_dim=ACT, feature_shapes={}, obs_key="state",
        force_key="force",
    )  # fmt: skip
    rewards.step()  # the reward on
    transform = rewards.transform[1]
    assert isinstance(transform, ICMReward) and transform.scale == pytest.approx(0.3)
    loss = rewards.losses["icm"]
    assert transform.params is loss.model_params and not rewards._updaters

    def by_hand(batch):
        with torch.no_grad():
            _, predicted_next, next_phi = loss.predict(batch)
        return 0.3 * (predicted_next - next_phi).pow(2).sum(-1, keepdim=True)

    batch = _transition()
    expected = by_hand(batch)
    got = rewards.transform(batch.clone())["next", keys.ICM_REWARD]
    assert got.shape == (6, 1) and (got > 0).all()
    torch.testing.assert_close(got, expected)
    rewards.extend(rewards.transform(batch.clone()))
    metrics = rewards.update(5)  # one [1, B] step of the ICM model (no ensemble axis)
    assert list(metrics) == ["model_icm"] and isinstance(metrics["model_icm"], float)
    assert rewards.num_updates == 5
    moved = rewards.transform(batch.clone())["next", keys.ICM_REWARD]
    torch.testing.assert_close(moved, by_hand(batch))
    assert not torch.allclose(moved, expected)


def test_the_dynamics_model_has_the_settings_sizes_seed_and_keys_and_its_surprise_their_scale():
    settings = GentlenessConfig(
        model_hidden=8, ensemble_size=2, surprise_scale=2.0, dynamics_surprise_scale=3.0
    )
    features = {"force": (2, 2)}
    rewards = IntrinsicRewards(
        "r+rf+rs", settings, obs_dim=OBS, action_dim=ACT, feature_shapes=features, seed=4,
        obs_key="state", force_key="force",
    )  # fmt: skip
    loss = rewards.losses["dynamics"]
    expected = DynamicsModel(OBS, ACT, features, 2, (8, 8, 8), seed=4, obs_key="state")
    _assert_same_parameters(loss.model_params, TensorDict.from_module(expected))
    assert loss.model.obs_key == "state"
    assert list(loss(_transition().expand(2, 6).clone()).keys()) == ["loss_dynamics"]
    transform = rewards.transform[1]
    assert isinstance(transform, DynamicsSurprise)
    assert transform.scale == 2.0 * 3.0  # surprise_scale x dynamics_surprise_scale
    assert transform.params is loss.target_model_params
    # the scaled surprise: 6 x eq. 6 under the target ensemble
    rewards.step(settings.reward_delay)
    plain = DynamicsSurprise(loss.model, loss.target_model_params, scale=1.0)
    plain.active.fill_(True)
    batch = _transition()
    torch.testing.assert_close(
        rewards.transform(batch.clone())["next", keys.DYNAMICS_SURPRISE],
        6.0 * plain(batch.clone())["next", keys.DYNAMICS_SURPRISE],
    )


@pytest.mark.parametrize(
    ("variant", "model", "period_setting"),
    [("r+rf+rs", "dynamics", "dynamics_target_period"),
     ("r+rf+rsp", "penalty", "penalty_target_period")],
)  # fmt: skip
def test_the_target_model_copies_the_online_one_every_target_period_updates(
    variant, model, period_setting
):
    settings = GentlenessConfig(model_hidden=8, ensemble_size=2, **{period_setting: 3})
    rewards = IntrinsicRewards(
        variant, settings, obs_dim=OBS, action_dim=ACT, feature_shapes={"force": (2, 2)},
        obs_key="state", force_key="force",
    )  # fmt: skip
    loss = rewards.losses[model]

    names = [k for k, p in loss.model_params.items(True, True) if p.requires_grad]
    assert names

    def weights(params):
        return [params[k].detach().clone() for k in names]

    initial = weights(loss.target_model_params)
    with torch.no_grad():
        for k in names:
            loss.model_params[k].add_(0.5)
    for _ in range(2):  # the first two steps: the target keeps the initial model
        rewards.step()
        for a, b in zip(weights(loss.target_model_params), initial, strict=True):
            assert torch.equal(a, b)
    rewards.step()  # the third: a copy of the moved model
    for a, b in zip(weights(loss.target_model_params), weights(loss.model_params), strict=True):
        assert torch.equal(a, b)


def test_the_wear_penalties_read_the_named_force_key_and_the_actuator_force():
    settings = GentlenessConfig(model_hidden=8, ensemble_size=2)
    rewards = IntrinsicRewards(
        "r+rf+rsp+rF", settings, obs_dim=OBS, action_dim=ACT, feature_shapes={},
        obs_key="state", force_key="force",
    )  # fmt: skip
    force = rewards.transform[-1]
    assert isinstance(force, ForcePenalty) and force.in_keys == ["force"]
    batch = _transition(batch=1)
    batch["next", "force"] = torch.tensor([[[8.0, 0.0], [0.0, 0.0]]])
    # ForcePenalty's own example: 8 N on one site at lam = [2, 8] costs 4
    out = rewards.transform(batch)["next", keys.FORCE_PENALTY]
    torch.testing.assert_close(out, torch.tensor([[-4.0]]))
    torque = IntrinsicRewards(
        "r+rf+rsp+rt", settings, obs_dim=OBS, action_dim=ACT, feature_shapes={},
        obs_key="state", force_key="force",
    ).transform[-1]  # fmt: skip
    assert isinstance(torque, TorquePenalty) and torque.in_keys == [keys.ACTUATOR_FORCE]
    effort = TensorDict(
        {keys.ACTUATOR_FORCE: torch.zeros(3), "next": {keys.ACTUATOR_FORCE: torch.tensor(
            [1.0, -1.0, 0.0])}}
    )  # fmt: skip
    torch.testing.assert_close(torque(effort)["next", keys.TORQUE_PENALTY], torch.tensor([-1.0]))


def test_the_penalty_model_is_built_under_seed_plus_1_and_its_surprise_takes_the_settings():
    settings = GentlenessConfig(
        model_hidden=8, ensemble_size=2, lam_prime=(3.0, 1.5), surprise_scale=0.5,
        surprise_nll_floor=0.25, surprise_kind="information_gain", curiosity_norm=True,
    )  # fmt: skip
    rewards = IntrinsicRewards(
        "r+rf+rsp", settings, obs_dim=OBS, action_dim=ACT, feature_shapes={}, seed=4,
        obs_key="state", force_key="force",
    )  # fmt: skip
    loss = rewards.losses["penalty"]
    expected = PenaltyModel(OBS, ACT, 2, (8, 8, 8), seed=4 + 1, obs_key="state")
    _assert_same_parameters(loss.model_params, TensorDict.from_module(expected))
    assert loss.model.obs_key == "state"
    batch = _transition().expand(2, 6).clone()
    batch["next", keys.PENALTY] = -torch.rand(2, 6, 1)
    assert list(loss(batch).keys()) == ["loss_penalty"]
    transform = rewards.transform[1]
    assert isinstance(transform, PenaltySurprise) and transform.params is loss.target_model_params
    assert transform.lam_prime == (3.0, 1.5) and transform.nll_scale == 0.5
    assert transform.nll_floor == 0.25 and transform.kind == "information_gain"
    assert transform.normalize and rewards._normalized == [transform]
