"""The compiled learner update gives the eager update's losses; the options fail or fall back clearly."""

import pytest
import torch
import torch._inductor.config
from tensordict import TensorDict
from torch._dynamo.utils import counters

from gentlerl.agent.learner import Learner
from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.objectives.launch import EagerOnBuildFailure

#: Eager vs compiled over 4 updates (inductor fuses and reorders float32 sums); measured: <= 2.4e-7.
RTOL, ATOL = 1e-5, 1e-6


def _learner(**options) -> Learner:
    torch.manual_seed(0)
    critic = make_critic(3, 1, 2, (8,), 5, v_min=-5.0, v_max=[5.0, 0.0])
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (8,)), critic, reward_keys=["reward", "penalty"])
    loss.make_value_estimator(gamma=0.9)
    return Learner(loss, lr_actor=1e-2, lr_critic=1e-2, target_update_period=2, **options)


def _batch(seed: int, n: int = 8) -> TensorDict:
    gen = torch.Generator().manual_seed(seed)
    nxt = {
        "observation": torch.randn(n, 3, generator=gen),
        "reward": torch.randn(n, 1, generator=gen),
        "penalty": -torch.rand(n, 1, generator=gen),
        "terminated": torch.rand(n, 1, generator=gen) < 0.3,
    }
    return TensorDict(
        {
            "observation": torch.randn(n, 3, generator=gen),
            "action": torch.rand(n, 1, generator=gen) * 2 - 1,
            "priority_weight": torch.rand(n, generator=gen),
            "index": torch.arange(n),  # a replay-buffer entry the loss does not read
            "next": nxt,
        },
        [n],
    )


def test_compiled_update_gives_the_eager_losses_priorities_and_parameters():
    counters.clear()
    eager, compiled = _learner(), _learner(compile=True)
    for seed in range(4):  # 4 updates: two target copies, Adam past its first step
        a, b = _batch(seed), _batch(seed)
        out_a, out_b = eager.update(a), compiled.update(b)
        assert out_a.keys() == out_b.keys()
        for key in out_a.keys():
            torch.testing.assert_close(out_b[key], out_a[key], rtol=RTOL, atol=ATOL)
        torch.testing.assert_close(b["td_error"], a["td_error"], rtol=RTOL, atol=ATOL)
    torch.testing.assert_close(
        compiled.loss.state_dict(), eager.loss.state_dict(), rtol=RTOL, atol=ATOL
    )
    assert compiled._losses.compiled is not None  # it ran compiled, not via the fallback
    # One graph: no host sync or data-dependent shape in the losses, projection or priorities.
    assert not counters["graph_break"], dict(counters["graph_break"])
    assert counters["stats"]["unique_graphs"] == 1


def test_update_writes_priorities_and_leaves_the_rest_of_the_batch():
    learner, batch = _learner(), _batch(0)
    before = batch.clone()
    out = learner.update(batch)
    assert "td_error" not in out.keys() and batch["td_error"].shape == (8,)
    assert (batch.exclude("td_error") == before).all()


def test_cudagraphs_on_cpu_is_a_one_line_error():
    with pytest.raises(
        ValueError, match="learner.cudagraphs needs a CUDA learner, this one is on cpu"
    ):
        _learner(cudagraphs=True)


def test_compile_falls_back_to_eager_with_the_reason(monkeypatch):
    from torch._inductor import cpp_builder

    def no_compiler():  # as inductor's own check fails without a C++ compiler
        raise RuntimeError("no working C++ compiler found")

    # (patching config.cpp.cxx instead would leave torch's config without it after the undo)
    monkeypatch.setattr(cpp_builder, "get_cpp_compiler", no_compiler)
    with pytest.warns(
        UserWarning, match="no C.. compiler for inductor .* the learner runs eagerly"
    ):
        learner = _learner(compile=True)
    learner.update(_batch(0))
    assert not isinstance(learner._losses, EagerOnBuildFailure)  # the eager function itself


def test_a_compiled_step_that_fails_to_build_runs_eagerly_and_says_why():
    calls = []

    def eager(x):
        calls.append(x)
        return x + 1

    def failing(x):
        inner = RuntimeError("'at::vec' has not been declared\n(the C++ that followed)")
        raise torch._dynamo.exc.BackendCompilerFailed(failing, inner, None)

    step = EagerOnBuildFailure(eager, failing)
    with pytest.warns(UserWarning, match="RuntimeError: 'at::vec' has not been declared\\); the"):
        assert step(1) == 2
    assert step(5) == 6 and calls == [1, 5] and step.compiled is None
    # Any other error is the step's own and is raised, not hidden by the fallback.
    step = EagerOnBuildFailure(eager, lambda x: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        step(1)
