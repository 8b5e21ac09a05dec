"""ModelStep: a reward model's step, eager or compiled, gives the same losses and parameters."""

import pytest
import torch

from gentlerl.models import PenaltyModel
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.objectives.compile import compile_unavailable
from gentlerl.rewards.model_step import ModelStep
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
