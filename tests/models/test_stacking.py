"""models.stacking: seeds' parameters stacked, shared row by row, the batched Adam's rows."""

import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torch.func import functional_call

from gentlerl.models.stacking import (
    SeedStack,
    load_optimizer_row,
    optimizer_row,
    share_rows,
    stack_optimizer_rows,
    stack_parameters,
)


def _module(seed):
    torch.manual_seed(seed)
    module = nn.Linear(3, 2)
    module.register_buffer("count", torch.tensor(float(seed)))
    return module


def test_stack_marks_weights_as_parameters_and_shared_rows_see_the_stacks_updates():
    modules = [_module(s) for s in (0, 1, 2)]
    own = [TensorDict.from_module(m, as_module=True) for m in modules]  # as a loss holds them
    stacked = stack_parameters(own)
    assert stacked["weight"].shape == (3, 2, 3) and isinstance(stacked["weight"], nn.Parameter)
    assert not isinstance(stacked["count"], nn.Parameter)
    torch.testing.assert_close(stacked["weight"][1], modules[1].weight)
    share_rows(stacked, own)
    with torch.no_grad():
        stacked["weight"].add_(1.0)
        stacked["count"].mul_(10.0)
    x = torch.ones(1, 3)
    for s, m in enumerate(modules):  # the modules act with the stack's rows, no copy
        torch.testing.assert_close(m(x), x @ stacked["weight"][s].T + stacked["bias"][s])
        assert float(own[s]["count"]) == 10.0 * s  # what a loss reads through to_module
    with pytest.raises(ValueError, match="share_rows: 2 seeds for a stack of 3 rows"):
        share_rows(stacked, own[:2])
    with pytest.raises(ValueError, match="needs at least one seed's parameters"):
        stack_parameters([])


def test_a_seeds_row_of_the_batched_adam_steps_as_if_it_had_stepped_alone():
    """optimizer_row hands out a seed's own Adam state; load_optimizer_row puts one back into its
    row (the others kept); both round trips step as Adams of their own would."""
    batched_param = nn.Parameter(torch.zeros(2, 4))
    batched = torch.optim.Adam([batched_param], lr=0.1)
    grads = torch.tensor([[1.0, 2.0, 3.0, 4.0], [-1.0, 0.5, 0.0, 2.0]])
    alone = [nn.Parameter(torch.zeros(4)) for _ in range(2)]
    alone_opt = [torch.optim.Adam([p], lr=0.1) for p in alone]
    for _ in range(3):
        batched_param.grad = grads.clone()
        batched.step()
        for s in range(2):
            alone[s].grad = grads[s].clone()
            alone_opt[s].step()
    rows = [optimizer_row(batched.state_dict(), s) for s in range(2)]
    for s in range(2):
        own = nn.Parameter(batched_param[s].detach().clone())
        single = torch.optim.Adam([own], lr=0.1)
        single.load_state_dict(rows[s])
        own.grad, alone[s].grad = grads[s].clone(), grads[s].clone()
        single.step()
        alone_opt[s].step()
        torch.testing.assert_close(own, alone[s])
        assert float(single.state[own]["step"]) == 4.0
    fresh_param = nn.Parameter(batched_param.detach().clone())
    fresh = torch.optim.Adam([fresh_param], lr=0.1)
    load_optimizer_row(fresh, alone_opt[1].state_dict(), 1, {})  # nothing stepped yet
    load_optimizer_row(fresh, alone_opt[0].state_dict(), 0, {})
    stacked = stack_optimizer_rows([alone_opt[s].state_dict() for s in range(2)])
    for key in ("exp_avg", "exp_avg_sq"):
        torch.testing.assert_close(fresh.state_dict()["state"][0][key], stacked["state"][0][key])
    with pytest.raises(ValueError, match="needs at least one seed's optimiser state"):
        stack_optimizer_rows([])


def test_a_seed_stack_is_s_adams_one_group_per_entry_the_others_frozen():
    """SeedStack: the rows shared with each seed's modules, one fused Adam whose groups are the
    entries given a step size (the rest frozen), and each seed's row of it a lone Adam's state."""
    modules = [[_module(s), _module(10 + s)] for s in (0, 1)]
    own = [TensorDict({"online": TensorDict.from_module(a), "target": TensorDict.from_module(b)})
           for a, b in modules]  # fmt: skip
    stack = SeedStack(own, {"online": 0.1}, capturable=False)
    assert stack.params.batch_size == (2,) and stack.options["fused"]
    assert [g["lr"] for g in stack.optimizer.param_groups] == [0.1]
    assert len(stack.optimizer.param_groups[0]["params"]) == 2  # weight, bias: not the count
    assert not stack.params["target", "weight"].requires_grad
    x = torch.randn(5, 3)
    alone = [nn.Linear(3, 2) for _ in (0, 1)]
    alone_opt = []
    for s, lin in enumerate(alone):
        lin.load_state_dict({k: v for k, v in modules[s][0].state_dict().items() if k != "count"})
        alone_opt.append(torch.optim.Adam(lin.parameters(), lr=0.1))
    for _ in range(2):
        rows = [{k: stack.params["online", k][s] for k in ("weight", "bias")} for s in (0, 1)]
        outs = [functional_call(m[0], row, (x,)) for m, row in zip(modules, rows, strict=True)]
        stack.descend(sum(out.square().sum() for out in outs))  # each seed's module, its row
        for lin, opt in zip(alone, alone_opt, strict=True):
            opt.zero_grad()
            lin(x).square().sum().backward()
            opt.step()
    for s in (0, 1):
        torch.testing.assert_close(modules[s][0].weight, alone[s].weight)
        row = stack.row(s)["state"][0]["exp_avg"]
        torch.testing.assert_close(row, alone_opt[s].state_dict()["state"][0]["exp_avg"])
    stack.load_row(stack.row(0), 1)
    assert torch.equal(*stack.optimizer.state_dict()["state"][0]["exp_avg"])
