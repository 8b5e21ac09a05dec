"""ModelStep: a reward model's step, eager or compiled, gives the same losses and parameters;
S seeds' steps in one equal S one-seed steps; a seed's optimiser row round-trips."""

import warnings
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.models import DynamicsModel, PenaltyModel
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.objectives.launch import compile_unavailable
from gentlerl.rewards.model_step import ModelStep, SeedBatchedModelStep
from tests.agent.test_learner import _batch


def _penalty_batch(seed):
    g = torch.Generator().manual_seed(seed)
    td = _batch(8).expand(2, 8).clone()
    td["observation"] = torch.randn(2, 8, 3, generator=g)
    td["action"] = torch.rand(2, 8, 1, generator=g)
    td["next", "penalty"] = -torch.rand(2, 8, 1, generator=g)
    return td


def _step(**options):
    torch.manual_seed(0)
    model = PenaltyModel(3, 1, ensemble_size=2, hidden=(8, 8))
    return ModelStep(EnsembleModelLoss(model, name="penalty"), 1e-2, **options)


def test_one_step_is_the_summed_loss_then_one_adam_step():
    step = _step()
    before = [p.detach().clone() for p in step.loss.parameters() if p.requires_grad]
    batch = _penalty_batch(0)
    expected = step.loss(batch.clone())["loss_penalty"].item()
    got = step(batch.unsqueeze(0))
    assert got.shape == (1,)  # one seed's summed loss, no host read
    assert got.item() == pytest.approx(expected, rel=1e-6)  # the loss before the step
    after = [p for p in step.loss.parameters() if p.requires_grad]
    assert all(not torch.equal(a, b) for a, b in zip(before, after, strict=True))


@pytest.mark.skipif(compile_unavailable() is not None, reason="no torch.compile here")
def test_the_compiled_step_gives_the_eager_losses_and_parameters():
    eager, compiled = _step(), _step(compile=True)
    for seed in range(3):
        a, b = eager(_penalty_batch(seed)[None]), compiled(_penalty_batch(seed)[None])
        torch.testing.assert_close(b, a, rtol=1e-5, atol=1e-6)
    for p, q in zip(eager.loss.parameters(), compiled.loss.parameters(), strict=True):
        torch.testing.assert_close(q, p, rtol=1e-5, atol=1e-6)


def test_cudagraphs_on_cpu_is_refused_in_one_line():
    with pytest.raises(
        ValueError, match="cudagraphs needs the models on a CUDA device, these are on cpu"
    ):
        _step(cudagraphs=True)


def _losses(seeds):
    return [
        EnsembleModelLoss(
            PenaltyModel(3, 1, ensemble_size=2, hidden=(8, 8), seed=s), name="penalty"
        )
        for s in seeds
    ]


def test_seed_batched_steps_equal_one_model_step_per_seed():
    """Weights, Adam state and the normaliser statistics of 3 seeds after 3 steps of one vmapped
    step equal those of 3 separate steps, seed by seed; the seeds stay different."""
    seeds = (0, 1, 2)
    singles = [ModelStep(loss, 1e-2) for loss in _losses(seeds)]
    batched = ModelStep(_losses(seeds), 1e-2)
    for k in range(3):
        batches = [_penalty_batch(10 * k + s) for s in seeds]
        expected = torch.cat(
            [step(b.clone()[None]) for step, b in zip(singles, batches, strict=True)]
        )
        got = batched(torch.stack(batches))
        assert got.shape == (3,)
        torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-6)
    for s, single in enumerate(singles):
        mine = batched.losses[s].model_params  # its own tensors: views of row s
        for key, value in single.loss.model_params.items(True, True):
            torch.testing.assert_close(mine[key], value, rtol=1e-5, atol=1e-6)
        row, own = batched.optimizer_state(s)["state"], single.optimizer_state()["state"]
        for index, moments in own.items():
            for name, value in moments.items():
                torch.testing.assert_close(row[index][name], value, rtol=1e-4, atol=1e-6)
    counts = batched.params.get(("input_norm", "count"))
    assert counts.shape == (3,) and torch.all(counts > 3 * 16)  # every step's 2 x 8 samples
    first = [p for p in batched.params.values(True, True) if p.requires_grad][0]
    assert not torch.allclose(first[0], first[1])


def test_a_model_step_refuses_a_batch_without_its_seeds_and_bad_settings():
    step = ModelStep(_losses((0, 1, 2)), 1e-2)
    with pytest.raises(ValueError, match=r"batch shaped \[num_seeds=3, ...\], got \(2, 8\)"):
        step(_penalty_batch(0))
    with pytest.raises(ValueError, match="needs at least one loss"):
        ModelStep([], 1e-2)
    with pytest.raises(TypeError, match=r"needs a loss with a pure losses\(batch, params\)"):
        ModelStep([torch.nn.Linear(2, 2)], 1e-2)
    with pytest.raises(ValueError, match="cudagraphs needs the models on a CUDA device"):
        ModelStep(_losses((0,)), 1e-2, cudagraphs=True)
    (loss,) = _losses((0,))  # the finding: one model trained as two seeds, each step twice
    with pytest.raises(ValueError, match="seeds 0 and 1 hold the same tensor .* passed twice"):
        ModelStep([loss, loss], 1e-2)
    for lr in (float("nan"), float("inf"), 0.0, -1e-3, True):
        with pytest.raises(ValueError, match=f"lr must be a finite number > 0, got {lr!r}"):
            ModelStep(_losses((0,)), lr)


def test_a_seeds_optimiser_row_loads_into_a_fresh_step_and_steps_as_before():
    """What a seed's checkpoint saves of a group's step (its row) resumes alone: the next step
    of a one-seed step loaded with it equals the group's next step of that seed."""
    batched = ModelStep(_losses((0, 1)), 1e-2)
    for k in range(2):
        batched(torch.stack([_penalty_batch(10 * k + s) for s in (0, 1)]))
    alone = ModelStep(_losses((5,)), 1e-2)  # another seed's weights, overwritten below
    alone.losses[0].load_state_dict(batched.losses[1].state_dict())
    alone.load_optimizer_state(batched.optimizer_state(1))
    nxt = [_penalty_batch(30 + s) for s in (0, 1)]
    expected = batched(torch.stack(nxt))[1]
    got = alone(nxt[1][None])[0]
    torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-6)
    for key, value in batched.losses[1].model_params.items(True, True):
        torch.testing.assert_close(alone.losses[0].model_params[key], value, rtol=1e-5, atol=1e-6)


def test_the_deprecated_seed_batched_step_warns_and_is_a_model_step():
    with pytest.warns(DeprecationWarning, match="SeedBatchedModelStep is deprecated since 0.2.0"):
        step = SeedBatchedModelStep(_losses((0, 1)), 1e-2, share=True)
    assert isinstance(step, ModelStep) and step.num_seeds == 2


def _dynamics_batch(seed):
    g = torch.Generator().manual_seed(seed)
    touch = torch.randn(2, 8, 2, 2, generator=g)
    return TensorDict(
        {
            keys.OBSERVATION: torch.randn(2, 8, 3, generator=g),
            keys.ACTION: torch.randn(2, 8, 2, generator=g),
            keys.TOUCH: touch,
            "next": {keys.TOUCH: touch + 0.5 * torch.randn(2, 8, 2, 2, generator=g)},
        },
        [2, 8],
    )


def test_seed_batched_dynamics_steps_equal_one_model_step_per_seed():
    """The dynamics ensemble (one ensemble and one delta normaliser per feature group) too."""

    def losses():
        return [
            EnsembleModelLoss(
                DynamicsModel(3, 2, {keys.TOUCH: (2, 2)}, ensemble_size=2, hidden=(8,), seed=s),
                name="dynamics",
            )
            for s in (0, 1)
        ]

    singles = [ModelStep(loss, 1e-2) for loss in losses()]
    batched = ModelStep(losses(), 1e-2)
    for k in range(2):
        batches = [_dynamics_batch(10 * k + s) for s in (0, 1)]
        expected = torch.cat(
            [step(b.clone()[None]) for step, b in zip(singles, batches, strict=True)]
        )
        torch.testing.assert_close(batched(torch.stack(batches)), expected, rtol=1e-5, atol=1e-6)
    for s, single in enumerate(singles):
        mine = batched.losses[s].model_params
        for key, value in single.loss.model_params.items(True, True):
            torch.testing.assert_close(mine[key], value, rtol=1e-5, atol=1e-6)


def test_the_deprecation_names_the_replacement_points_past_the_shim_and_passes_options_on():
    with pytest.warns(DeprecationWarning) as record:
        SeedBatchedModelStep(_losses((0, 1)), 1e-2)
    (warning,) = record
    assert str(warning.message) == (
        "gentlerl.rewards.model_step.SeedBatchedModelStep is deprecated since 0.2.0 and "
        "removed in 0.3.0: use ModelStep(losses, lr), which takes one loss per seed"
    )
    assert Path(warning.filename).name != "model_step.py"  # the caller's line, not the shim's
    with (
        pytest.warns(DeprecationWarning),
        pytest.raises(ValueError, match="cudagraphs needs the models on a CUDA device"),
    ):
        SeedBatchedModelStep(_losses((0,)), 1e-2, cudagraphs=True)


def test_a_step_takes_a_batch_with_a_seed_axis_and_one_batch_axis():
    """A model without an ensemble axis (ICM) steps on ``[S, B]``: two batch dims suffice."""
    from gentlerl.models import ICMModel
    from gentlerl.objectives import ICMLoss

    torch.manual_seed(0)
    step = ModelStep(ICMLoss(ICMModel(3, 1, feature_dim=4, hidden=8)), 1e-2)
    batch = _penalty_batch(0)[0]  # [8]: observation [8, 3], action [8, 1]
    batch["next", "observation"] = batch["observation"] + 0.1
    expected = step.loss(batch.clone())["loss_icm"].item()
    got = step(batch.unsqueeze(0))
    assert got.shape == (1,) and got.item() == pytest.approx(expected, rel=1e-6)


def test_the_first_adam_step_moves_every_weight_by_the_learning_rate():
    """Adam's first step is lr * m / (sqrt(v) + eps) = lr * g / (|g| + eps): each weight moves by
    lr (1e-2 here), up to eps / |g|, in one fused kernel."""
    step = _step()
    assert step.optimizer.defaults["fused"] is True
    before = [p.detach().clone() for p in step.optimizer.param_groups[0]["params"]]
    step(_penalty_batch(0).unsqueeze(0))
    for old, new in zip(before, step.optimizer.param_groups[0]["params"], strict=True):
        moved = (new.detach() - old).abs()
        expected = torch.where(new.grad != 0, 1e-2, 0.0)  # a dead unit's weights stay
        assert (new.grad != 0).float().mean() > 0.5
        torch.testing.assert_close(moved, expected, rtol=1e-3, atol=1e-5)


def test_without_torch_compile_the_step_warns_naming_the_reward_models_and_runs_eagerly(
    monkeypatch,
):
    from gentlerl.objectives import launch as compiling

    monkeypatch.setattr(compiling, "compile_unavailable", lambda: "no C++ compiler (test)")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _step()  # eager by default: nothing to fall back from
    with pytest.warns(UserWarning) as record:
        step = _step(compile=True)
    assert [str(w.message) for w in record] == [
        "learner.compile: no C++ compiler (test); the reward models runs eagerly"
    ]
    assert step(_penalty_batch(0).unsqueeze(0)).shape == (1,)


def test_the_refusals_name_what_they_got_in_full():
    with pytest.raises(
        ValueError, match=r"^ModelStep needs at least one loss \(one per seed\), got 0$"
    ):
        ModelStep([], 1e-2)
    with pytest.raises(
        TypeError,
        match=r"^ModelStep needs a loss with a pure losses\(batch, params\) \(e.g. "
        r"EnsembleModelLoss\), got Linear$",
    ):
        ModelStep([torch.nn.Linear(2, 2)], 1e-2)
