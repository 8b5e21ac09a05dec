"""ModelStep: a reward model's step, eager or compiled, gives the same losses and parameters;
SeedBatchedModelStep: S seeds' steps in one equal S ModelSteps."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.models import DynamicsModel, PenaltyModel
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.objectives.compile import compile_unavailable
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
    got = step(batch)
    assert got == pytest.approx(expected, rel=1e-6)  # the loss before the step
    after = [p for p in step.loss.parameters() if p.requires_grad]
    assert all(not torch.equal(a, b) for a, b in zip(before, after, strict=True))


@pytest.mark.skipif(compile_unavailable() is not None, reason="no torch.compile here")
def test_the_compiled_step_gives_the_eager_losses_and_parameters():
    eager, compiled = _step(), _step(compile=True)
    for seed in range(3):
        a, b = eager(_penalty_batch(seed)), compiled(_penalty_batch(seed))
        assert b == pytest.approx(a, rel=1e-5, abs=1e-6)
    for p, q in zip(eager.loss.parameters(), compiled.loss.parameters(), strict=True):
        torch.testing.assert_close(q, p, rtol=1e-5, atol=1e-6)


def test_cudagraphs_on_cpu_is_refused_in_one_line():
    with pytest.raises(
        ValueError, match="cudagraphs needs the model on a CUDA device, this one is"
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
    batched = SeedBatchedModelStep(_losses(seeds), 1e-2)
    for k in range(3):
        batches = [_penalty_batch(10 * k + s) for s in seeds]
        expected = torch.tensor([step(b.clone()) for step, b in zip(singles, batches, strict=True)])
        got = batched(torch.stack(batches))
        assert got.shape == (3,)
        torch.testing.assert_close(got, expected, rtol=1e-5, atol=1e-6)
    for s, single in enumerate(singles):
        mine = batched.write_back(s).model_params
        for key, value in single.loss.model_params.items(True, True):
            torch.testing.assert_close(mine[key], value, rtol=1e-5, atol=1e-6)
    counts = batched.params.get(("input_norm", "count"))
    assert counts.shape == (3,) and torch.all(counts > 3 * 16)  # every step's 2 x 8 samples
    first = [p for p in batched.params.values(True, True) if p.requires_grad][0]
    assert not torch.allclose(first[0], first[1])


def test_seed_batched_model_step_refuses_a_batch_without_its_seeds():
    step = SeedBatchedModelStep(_losses((0, 1, 2)), 1e-2)
    with pytest.raises(ValueError, match=r"batch shaped \[num_seeds=3, ...\], got \(2, 8\)"):
        step(_penalty_batch(0))
    with pytest.raises(ValueError, match="needs at least one loss"):
        SeedBatchedModelStep([], 1e-2)
    with pytest.raises(TypeError, match=r"needs a loss with a pure losses\(batch, params\)"):
        SeedBatchedModelStep([torch.nn.Linear(2, 2)], 1e-2)
    with pytest.raises(ValueError, match="cudagraphs needs the models on a CUDA device"):
        SeedBatchedModelStep(_losses((0,)), 1e-2, cudagraphs=True)


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
    batched = SeedBatchedModelStep(losses(), 1e-2)
    for k in range(2):
        batches = [_dynamics_batch(10 * k + s) for s in (0, 1)]
        expected = torch.tensor([step(b.clone()) for step, b in zip(singles, batches, strict=True)])
        torch.testing.assert_close(batched(torch.stack(batches)), expected, rtol=1e-5, atol=1e-6)
    for s, single in enumerate(singles):
        mine = batched.write_back(s).model_params
        for key, value in single.loss.model_params.items(True, True):
            torch.testing.assert_close(mine[key], value, rtol=1e-5, atol=1e-6)
