"""objectives.model_losses: the ICM loss (Pathak et al. 2017, eq. 7) against its equations computed by
hand on a tiny model, and the ensemble losses' target predictions (``predict_target``).

The target copies' normaliser statistics (``ModelHardUpdate``) are tested in
``test_model_target.py``."""

import re
import warnings

import pytest
import torch
from tensordict import TensorDict

from gentlerl.models import ICMModel, PenaltyModel
from gentlerl.objectives import EnsembleModelLoss, ICMLoss, ModelHardUpdate

OBS, ACT, FEAT, HIDDEN = 2, 1, 2, 3


def _icm(seed):
    torch.manual_seed(seed)
    return ICMModel(OBS, ACT, FEAT, HIDDEN)


def _batch(n=5, seed=0, next_obs=None):
    g = torch.Generator().manual_seed(seed)
    return TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "action": torch.rand(n, ACT, generator=g) * 2 - 1,
            "next": {
                "observation": (torch.randn(n, OBS, generator=g) if next_obs is None else next_obs)
            },
        },
        [n],
    )


def _mlp(x, p):
    """``Linear -> ReLU -> Linear`` written out: ``relu(x W0^T + b0) W2^T + b2``."""
    h = torch.relu(x @ p["0", "weight"].T + p["0", "bias"])
    return h @ p["2", "weight"].T + p["2", "bias"]


def _by_hand(td, p, beta):
    """Eq. 7 with the ICM's three networks written out, ``phi(s_{t+1})`` detached in the forward
    term: ``(loss, inverse, forward)``."""
    obs, action, next_obs = td["observation"], td["action"], td["next", "observation"]
    phi, next_phi = _mlp(obs, p["encoder"]), _mlp(next_obs, p["encoder"])
    predicted_action = torch.tanh(_mlp(torch.cat([phi, next_phi], -1), p["inverse"]))
    predicted_next = _mlp(torch.cat([phi, action], -1), p["forward_model"])
    # MSE over batch and action dimensions
    inverse = ((predicted_action - action) ** 2).sum() / action.numel()
    # 1/2 ||phi_hat - phi||^2 summed over features, mean over the batch
    forward = 0.5 * ((predicted_next - next_phi.detach()) ** 2).sum(-1).sum() / obs.shape[0]
    return (1 - beta) * inverse + beta * forward, inverse, forward


@pytest.mark.parametrize("beta", [None, 0.0, 0.5, 1.0])
def test_icm_loss_is_eq_7_with_its_terms_by_hand(beta):
    loss = ICMLoss(_icm(1)) if beta is None else ICMLoss(_icm(1), beta=beta)
    beta = 0.2 if beta is None else beta  # the paper's default
    assert loss.beta == beta
    td = _batch()
    out = loss(td)
    expected, inverse, forward = _by_hand(td, loss.model_params, beta)
    assert set(out.keys()) == {"loss_icm", "icm_inverse", "icm_forward"}
    assert out.batch_size == torch.Size([])
    assert inverse > 0 and forward > 0 and not torch.isclose(inverse, forward)
    torch.testing.assert_close(out["icm_inverse"], inverse.detach())
    torch.testing.assert_close(out["icm_forward"], forward.detach())
    torch.testing.assert_close(out["loss_icm"], expected)
    # the terms are logged, detached; the loss carries the gradient
    assert not out["icm_inverse"].requires_grad and not out["icm_forward"].requires_grad
    assert out["loss_icm"].requires_grad


def test_icm_gradients_are_those_of_eq_7_with_the_next_features_detached():
    loss = ICMLoss(_icm(2), beta=0.3)
    td = _batch(seed=3)
    grads = torch.autograd.grad(loss(td)["loss_icm"], list(loss.model_params.values(True, True)))
    expected = _by_hand(td, loss.model_params, 0.3)[0]
    by_hand = torch.autograd.grad(expected, list(loss.model_params.values(True, True)))
    for got, want in zip(grads, by_hand, strict=True):
        torch.testing.assert_close(got, want)


@pytest.mark.parametrize("beta", [1.0, 0.2])
def test_the_forward_term_sends_no_gradient_through_the_next_features(beta):
    """``s_{t+1}`` enters the forward term only through ``phi(s_{t+1})``, which is detached: with
    beta = 1 (the forward term alone) it gets no gradient; with the inverse term it does."""
    next_obs = torch.randn(5, OBS, generator=torch.Generator().manual_seed(7), requires_grad=True)
    loss = ICMLoss(_icm(4), beta=beta)
    (grad,) = torch.autograd.grad(
        loss(_batch(next_obs=next_obs))["loss_icm"], next_obs, allow_unused=True
    )
    if beta == 1.0:
        assert grad is None or torch.count_nonzero(grad) == 0
    else:
        assert grad is not None and torch.count_nonzero(grad) > 0
    # the encoder still learns from the forward term through phi(s_t)
    encoder = list(loss.model_params["encoder"].values(True, True))
    grads = torch.autograd.grad(loss(_batch(seed=8))["loss_icm"], encoder)
    assert all(torch.count_nonzero(g) > 0 for g in grads)


@pytest.mark.parametrize("beta", [-0.01, 1.01, -1.0, 2.0])
def test_icm_refuses_a_beta_outside_0_1(beta):
    with pytest.raises(ValueError, match=rf"^beta must be in \[0, 1\], got {beta}$"):
        ICMLoss(_icm(0), beta=beta)


@pytest.mark.parametrize("beta", [0.0, 1.0, 0.2])
def test_icm_accepts_beta_in_0_1_bounds_included(beta):
    assert ICMLoss(_icm(0), beta=beta).beta == beta


def test_icm_keeps_no_target_copy():
    loss = ICMLoss(_icm(0))
    assert all(k.startswith("model_params.") for k in loss.state_dict())
    assert list(loss.buffers()) == []
    assert {n for n, _ in loss.named_parameters()} == {
        "model_params." + ".".join(k) for k in loss.model_params.keys(True, True)
    }


def test_losses_with_other_params_is_the_loss_of_that_model_and_leaves_its_own():
    loss, other = ICMLoss(_icm(5)), ICMLoss(_icm(6))
    own = loss.model_params.detach().clone()
    td = _batch(seed=9)
    before = loss(td)
    out = loss.losses(td, other.model_params)
    expected = other(td)
    for key in ("loss_icm", "icm_inverse", "icm_forward"):
        torch.testing.assert_close(out[key], expected[key])
        assert not torch.isclose(out[key], before[key])
    torch.testing.assert_close(out["loss_icm"], _by_hand(td, other.model_params, 0.2)[0])
    # pure: the loss's own parameters are the same tensors with the same values
    for key, value in own.items(True, True):
        torch.testing.assert_close(loss.model_params.get(key), value, rtol=0, atol=0)
    for key in ("loss_icm", "icm_inverse", "icm_forward"):
        torch.testing.assert_close(loss(td)[key], before[key], rtol=0, atol=0)
    # the gradient of losses(td, params) reaches params, not the loss's own parameters
    out["loss_icm"].backward()
    assert all(p.grad is None for p in loss.parameters())
    assert all(p.grad is not None for p in other.parameters())


def _predictions_by_hand(td, p):
    obs, action, next_obs = td["observation"], td["action"], td["next", "observation"]
    phi, next_phi = _mlp(obs, p["encoder"]), _mlp(next_obs, p["encoder"])
    predicted_action = torch.tanh(_mlp(torch.cat([phi, next_phi], -1), p["inverse"]))
    return predicted_action, _mlp(torch.cat([phi, action], -1), p["forward_model"]), next_phi


def test_predict_uses_its_own_params_by_default_and_the_given_ones_otherwise():
    loss, other = ICMLoss(_icm(10)), ICMLoss(_icm(11))
    td = _batch(seed=12)
    own = loss.predict(td)
    assert len(own) == 3
    for got, want in zip(own, _predictions_by_hand(td, loss.model_params), strict=True):
        torch.testing.assert_close(got, want)
    given = loss.predict(td, other.model_params)
    for got, want, mine in zip(
        given, _predictions_by_hand(td, other.model_params), own, strict=True
    ):
        torch.testing.assert_close(got, want)
        assert not torch.allclose(got, mine)
    assert [t.shape for t in own] == [(5, ACT), (5, FEAT), (5, FEAT)]


# --- EnsembleModelLoss.predict_target ---------------------------------------------------------


def _penalty_batch(n=6, seed=0):
    g = torch.Generator().manual_seed(seed)
    return TensorDict(
        {
            "observation": torch.randn(n, 3, generator=g) * 2 + 1,
            "action": torch.rand(n, 2, generator=g),
            "next": {"penalty": -torch.rand(n, 1, generator=g)},
        },
        [n],
    )


def _predict_with(loss, params, td):
    with torch.no_grad(), params.to_module(loss.model):
        return loss.model.predict(td)


def test_predict_target_reads_the_target_until_a_copy_then_the_online_model():
    loss = EnsembleModelLoss(
        PenaltyModel(3, 2, ensemble_size=2, hidden=(4,)), name="penalty", per_member=False
    )
    updater = ModelHardUpdate(loss, value_network_update_interval=0)
    td = _penalty_batch()
    initial = _predict_with(loss, loss.model_params, td)
    with torch.no_grad():  # a training step moves the online weights and statistics
        for value in loss.model_params.values(True, True):
            value.add_(0.1 * torch.randn_like(value))
    loss(td)  # training mode: merges the batch into the online normaliser statistics
    online = _predict_with(loss, loss.model_params, td)
    target = loss.predict_target(td)
    assert isinstance(target, tuple) and len(target) == 2
    for got, was, now in zip(target, initial, online, strict=True):
        assert got.shape == (2, 6, 1)
        torch.testing.assert_close(got, was, rtol=0, atol=0)
        assert not torch.allclose(got, now)
        assert not got.requires_grad and got.grad_fn is None
    updater.step()  # the copy
    for got, now in zip(loss.predict_target(td), online, strict=True):
        torch.testing.assert_close(got, now, rtol=0, atol=0)
        assert not got.requires_grad
    # predict_target leaves the online parameters as they were
    for got, now in zip(_predict_with(loss, loss.model_params, td), online, strict=True):
        torch.testing.assert_close(got, now, rtol=0, atol=0)


def test_icm_forward_term_sums_the_features_of_a_batch_of_any_shape():
    """A ``[2, 4]`` batch: the forward term sums over the features and averages the 8 samples."""
    loss = ICMLoss(_icm(13))
    td = TensorDict(
        {
            "observation": torch.randn(2, 4, OBS),
            "action": torch.rand(2, 4, ACT) * 2 - 1,
            "next": {"observation": torch.randn(2, 4, OBS)},
        },
        [2, 4],
    )
    out = loss(td)
    _, inverse, forward = _by_hand(td.reshape(-1), loss.model_params, 0.2)
    torch.testing.assert_close(out["icm_forward"], forward.detach())
    torch.testing.assert_close(out["icm_inverse"], inverse.detach())


def test_icm_with_detached_params_computes_without_gradient_or_warning():
    """Parameters given as plain tensors (a frozen copy) stay plain: no gradient, no warning."""
    loss = ICMLoss(_icm(14))
    td = _batch(seed=15)
    frozen = loss.model_params.detach()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        predictions = loss.predict(td, frozen)
        out = loss.losses(td, frozen)
    assert not any(t.requires_grad for t in predictions)
    assert not out["loss_icm"].requires_grad
    torch.testing.assert_close(out["loss_icm"], _by_hand(td, loss.model_params, 0.2)[0].detach())


# --- EnsembleModelLoss: eq. 6 / 8's Gaussian NLL, per member or shared ------------------------

E, B = 2, 4


def _penalty_loss(**kwargs):
    torch.manual_seed(20)
    loss = EnsembleModelLoss(PenaltyModel(3, 2, ensemble_size=E, hidden=(4,)), **kwargs)
    ModelHardUpdate(loss, value_network_update_interval=10)  # the target's updater
    return loss.eval()  # the normaliser statistics stay put


def _nll_by_hand(loss, td):
    """``-log N(y | mu, var)`` of every member on every sample of ``td``: ``[E, *batch]``."""
    with torch.no_grad(), loss.model_params.to_module(loss.model):
        mean, var = loss.model.predict(td)
    y = td["next", "penalty"]
    return (0.5 * (torch.log(2 * torch.pi * var) + (y - mean) ** 2 / var)).squeeze(-1)


def test_ensemble_loss_per_member_reads_member_e_on_its_own_rows():
    loss = _penalty_loss(name="penalty")
    assert loss.per_member is True  # the default: bootstrap
    td = _penalty_batch(E * B, seed=21).reshape(E, B)
    out = loss(td)
    assert set(out.keys()) == {"loss_penalty"} and out.batch_size == torch.Size([])
    rows = torch.stack([_nll_by_hand(loss, td[e])[e] for e in range(E)])
    torch.testing.assert_close(out["loss_penalty"], rows.mean())
    shared = _nll_by_hand(loss, td.reshape(-1)).mean()
    assert not torch.isclose(out["loss_penalty"], shared)


def test_ensemble_loss_shared_batch_reads_every_member_on_every_row():
    loss = _penalty_loss(name="pen", per_member=False)
    td = _penalty_batch(E * B, seed=22)
    out = loss(td)
    assert set(out.keys()) == {"loss_pen"}
    torch.testing.assert_close(out["loss_pen"], _nll_by_hand(loss, td).mean())


def test_ensemble_loss_bootstraps_a_flat_batch_once_per_member():
    loss = _penalty_loss(name="penalty")
    td = _penalty_batch(B, seed=23)
    torch.manual_seed(24)
    out = loss(td)
    torch.manual_seed(24)
    index = torch.randint(B, (E, B))
    resampled = td[index]
    rows = torch.stack([_nll_by_hand(loss, resampled[e])[e] for e in range(E)])
    torch.testing.assert_close(out["loss_penalty"], rows.mean())


@pytest.mark.parametrize("n", [1, E, 5])
def test_bootstrap_shapes_a_flat_batch_as_members_by_rows(n):
    loss = _penalty_loss(name="penalty")
    td = _penalty_batch(n, seed=25)
    out = loss.bootstrap(td)
    assert out.batch_size == (E, n)
    assert all(any(torch.equal(row, x) for x in td["observation"]) for row in out["observation"][0])
    assert loss.bootstrap(td.reshape(1, n).expand(E, n)).batch_size == (E, n)


@pytest.mark.parametrize("shape", [(0,), (E + 1, 3), (1, 3), (E, 2, 3)])
def test_bootstrap_refuses_other_shapes_with_its_message(shape):
    loss = _penalty_loss(name="penalty")
    td = _penalty_batch(3, seed=26).expand(*shape[:-1], 3) if len(shape) > 1 else _penalty_batch(0)
    message = (
        rf"^per_member=True needs a flat batch \[B\] or one shaped \[ensemble_size={E}, B\], "
        rf"got {re.escape(str(tuple(td.batch_size)))}$"
    )
    with pytest.raises(ValueError, match=message):
        loss.bootstrap(td)


@pytest.mark.parametrize("name", ["", "two words", "1st", "loss-x"])
def test_ensemble_loss_refuses_a_name_that_is_no_identifier(name):
    message = (
        rf"^name must be an identifier \(it becomes loss_<name>\), got {re.escape(repr(name))}$"
    )
    with pytest.raises(ValueError, match=message):
        EnsembleModelLoss(PenaltyModel(3, 2, ensemble_size=E, hidden=(4,)), name=name)


def test_ensemble_losses_with_detached_params_computes_without_gradient_or_warning():
    loss = _penalty_loss(name="penalty", per_member=False)
    td = _penalty_batch(B, seed=27)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = loss.losses(td, loss.model_params.detach())
        target = loss.predict_target(td)
    assert not out["loss_penalty"].requires_grad
    torch.testing.assert_close(out["loss_penalty"], _nll_by_hand(loss, td).mean())
    assert not any(t.requires_grad for t in target)


@pytest.mark.parametrize("interval", [-1, 1.5, "5", True, None])
def test_a_target_update_interval_that_never_copies_is_refused(interval):
    """TorchRL's HardUpdate takes any of these and then never copies the target (the counter
    never equals -1, 1.5 or "5"): the surprise would read the initial model for ever."""
    loss = EnsembleModelLoss(PenaltyModel(3, 2, ensemble_size=2, hidden=(4,)), name="penalty")
    with pytest.raises(ValueError, match=rf"interval must be an integer >= 0.*got {interval!r}"):
        ModelHardUpdate(loss, value_network_update_interval=interval)
