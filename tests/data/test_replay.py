"""Replay: n-step sums of several reward components, the window-end terminated flag, priorities."""

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.data import PrioritizedSampler

from gentlerl import keys
from gentlerl.data import NStepWriter, make_beta_scheduler, make_model_buffer, make_replay_buffer


def _trajectory(T=8, terminal_at=4):
    """obs t = t; reward 1 every step; penalty -t; the episode terminates at step `terminal_at`."""
    term = torch.zeros(T, 1, dtype=torch.bool)
    term[terminal_at] = True
    return TensorDict(
        {
            "observation": torch.arange(T).float().unsqueeze(-1),
            "next": {
                "observation": torch.arange(1, T + 1).float().unsqueeze(-1),
                "reward": torch.ones(T, 1),
                "penalty": -torch.arange(T).float().unsqueeze(-1),
                "done": term.clone(),
                "terminated": term.clone(),
                "truncated": torch.zeros(T, 1, dtype=torch.bool),
            },
        },
        [T],
    )


def test_n_step_sums_every_reward_key_and_flags_the_window_end():
    rb = make_replay_buffer(
        100, 4, prioritized=False, n_steps=3, gamma=0.5, reward_keys=["reward", "penalty"]
    )
    rb.extend(_trajectory())
    data = rb[:]
    # The last n_steps transitions wait for the next write: 8 - 3 = 5 stored.
    assert len(rb) == 5
    # t=0: 1 + .5 + .25 = 1.75; t=3: window cut by the terminal step 4 -> 1 + .5 = 1.5.
    assert data["next", "reward"].squeeze(-1).tolist() == [1.75, 1.75, 1.75, 1.5, 1.0]
    # penalty t=0: -(0 + .5*1 + .25*2) = -1.0; t=3: -(3 + .5*4) = -5.
    assert data["next", "penalty"].squeeze(-1).tolist() == [-1.0, -2.75, -4.5, -5.0, -4.0]
    assert data["steps_to_next_obs"].tolist() == [3, 3, 3, 2, 1]
    assert data["next", "observation"].squeeze(-1).tolist() == [3.0, 4.0, 5.0, 5.0, 5.0]
    # t=2..4 reach the terminal step within their window: no bootstrap for them.
    assert data["next", keys.NSTEP_TERMINATED].squeeze(-1).tolist() == [
        False,
        False,
        True,
        True,
        True,
    ]


def test_prioritised_sampling_follows_td_error():
    torch.manual_seed(0)
    rb = make_replay_buffer(100, 256, n_steps=1, alpha=1.0, beta=0.4)
    assert isinstance(rb.sampler, PrioritizedSampler)
    rb.extend(_trajectory(T=11, terminal_at=10))  # 10 stored
    batch = rb.sample()
    batch[keys.PRIORITY] = torch.where(batch["observation"].squeeze(-1) == 0, 100.0, 1e-3)
    rb.update_tensordict_priority(batch)
    counts = (rb.sample()["observation"].squeeze(-1) == 0).float().mean()
    assert counts > 0.9  # priority 100 vs 9 x 0.001
    assert "priority_weight" in batch.keys()


def test_beta_scheduler_anneals_to_one():
    rb = make_replay_buffer(10, 2, beta=0.4)
    scheduler = make_beta_scheduler(rb, final_beta=1.0, num_steps=3)
    for _ in range(3):
        scheduler.step()
    assert rb.sampler.beta == pytest.approx(1.0)
    with pytest.raises(ValueError, match="prioritised"):
        make_beta_scheduler(make_replay_buffer(10, 2, prioritized=False))


def test_model_buffer_keeps_one_step_transitions():
    rb = make_model_buffer(100, 4)
    rb.extend(_trajectory())
    assert len(rb) == 8
    assert rb[:]["next", "observation"].squeeze(-1).tolist() == list(range(1, 9))


@pytest.mark.parametrize(
    "kwargs", [dict(capacity=0), dict(batch_size=0), dict(n_steps=0), dict(gamma=2.0)]
)
def test_bad_sizes_raise(kwargs):
    args = dict(capacity=10, batch_size=2) | kwargs
    with pytest.raises(ValueError):
        make_replay_buffer(**args)


def test_flat_tree_sum_min_and_prefix_search():
    from gentlerl.data import FlatPriorityTree

    tree = FlatPriorityTree(5, "sum", torch.float64)
    tree[torch.tensor([0, 1, 2, 3])] = torch.tensor([1.0, 0.0, 2.0, 3.0])
    assert tree.query(0, 4) == 6.0 and tree.query(2, 4) == 5.0
    # prefix sums 1, 1, 3, 6: mass 0.5 -> 0, 1.0 -> 2 (index 1 has no mass), 2.9 -> 2, 5.99 -> 3
    assert tree.scan_lower_bound(torch.tensor([0.5, 1.0, 2.9, 5.99])).tolist() == [0, 2, 2, 3]
    low = FlatPriorityTree(5, "min", torch.float64)
    low[torch.tensor([0, 1, 2])] = torch.tensor([4.0, 0.5, 2.0])
    assert low.query(0, 3) == 0.5 and low.query(2, 3) == 2.0


def test_sampling_frequencies_match_priorities_to_the_alpha():
    # alpha = 0.5: priorities 1, 4, 16 -> probabilities proportional to 1, 2, 4.
    torch.manual_seed(0)
    np.random.seed(0)
    rb = make_replay_buffer(10, 70_000, n_steps=1, alpha=0.5)
    rb.extend(_trajectory(T=4, terminal_at=3))  # 3 stored (t = 0, 1, 2)
    td = rb[:]
    td[keys.PRIORITY] = torch.tensor([1.0, 4.0, 16.0])
    td["index"] = torch.arange(3)
    rb.update_tensordict_priority(td)
    obs = rb.sample()["observation"].squeeze(-1).long()
    freq = torch.bincount(obs, minlength=3).float() / obs.numel()
    torch.testing.assert_close(freq, torch.tensor([1.0, 2.0, 4.0]) / 7, atol=0.01, rtol=0)


def test_nstep_writer_keeps_each_env_row_apart_and_resumes_with_a_cut():
    # Two env rows written as one [2, T] batch give the rows' windows, row by row; no window
    # mixes rows (row 1's observations are offset by 100).
    rows = [_trajectory(T=8, terminal_at=2), _trajectory(T=8, terminal_at=2)]
    rows[1]["observation"] += 100
    rows[1]["next", "observation"] += 100
    keys_ = ["reward", "penalty"]
    writer = NStepWriter(make_replay_buffer(100, 4, n_steps=None), 3, 0.5, keys_)
    writer.extend(torch.stack(rows))
    reference = make_replay_buffer(
        100, 4, prioritized=False, n_steps=3, gamma=0.5, reward_keys=keys_
    )
    reference.extend(rows[0])
    stored = writer.rb[:]
    assert len(writer.rb) == 2 * 5 and writer.tail.shape == (2, 3)
    assert (stored[:5] == reference[:]).all()
    assert (stored[5:]["next", "observation"] - stored[5:]["observation"] <= 3).all()
    # Resuming: the tail comes back with its last step truncated, so its windows end there.
    resumed = NStepWriter(make_replay_buffer(100, 4, n_steps=None), 3, 0.5, keys_)
    resumed.load_state_dict(writer.state_dict())
    assert len(resumed.rb) == 0 and resumed.tail["next", "truncated"][:, -1].all()
    resumed.extend(torch.stack([_trajectory(T=4, terminal_at=3)] * 2))
    first = resumed.rb[:]
    # Row 0's windows from t = 6 and 7 stop at the cut (t = 7) instead of reaching the new batch.
    assert first["steps_to_next_obs"][:3].flatten().tolist() == [3, 2, 1]
    assert first["next", "observation"][:3].flatten().tolist() == [8.0, 8.0, 8.0]
    with pytest.raises(ValueError, match="without transforms"):
        NStepWriter(make_replay_buffer(100, 4), 3, 0.5, keys_)


def test_the_torch_sampler_logs_no_cpp_extension_warning():
    """TorchRL's sampler warns that its C++ trees did not load; ours does not use them.

    The filter is scoped to the constructor, so TorchRL's logger is left as it was.
    """
    import logging

    from torchrl._extension import EXTENSION_WARNING
    from torchrl._utils import logger as torchrl_logger

    from gentlerl.data.prioritized import TorchPrioritizedSampler

    records: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record):
            records.append(record.getMessage())

    handler = Keep(level=logging.DEBUG)
    filters, level, disabled = (
        list(torchrl_logger.filters),
        torchrl_logger.level,
        torchrl_logger.disabled,
    )
    torchrl_logger.addHandler(handler)
    # whatever RL_LOGGING_LEVEL set, and on after a hydra app in this process disabled it
    torchrl_logger.setLevel(logging.DEBUG)
    torchrl_logger.disabled = False
    muted = logging.root.manager.disable
    logging.disable(logging.NOTSET)
    try:
        sampler = TorchPrioritizedSampler(16, alpha=0.6, beta=0.4)
        torchrl_logger.warning(EXTENSION_WARNING)  # outside the constructor it still gets through
    finally:
        torchrl_logger.removeHandler(handler)
        torchrl_logger.setLevel(level)
        torchrl_logger.disabled = disabled
        logging.disable(muted)
    assert records == [EXTENSION_WARNING]
    assert torchrl_logger.filters == filters
    assert sampler._alpha == 0.6 and sampler._beta == 0.4  # TorchRL's arguments, unchanged


def test_the_priority_search_reads_only_the_entries_written():
    """The prefix-sum search scans the written extent (25k of 1M slots: ~12x less work) and
    finds what a scan of every slot finds; a restored tree recovers its extent."""
    from gentlerl.data.prioritized import FlatPriorityTree

    tree = FlatPriorityTree(100_000, "sum", torch.float64)
    gen = torch.Generator().manual_seed(0)
    tree[torch.arange(2_500)] = torch.rand(2_500, generator=gen, dtype=torch.float64)
    tree[7] = 0.5
    assert tree.extent == 2_500
    total = float(tree.values.sum())
    mass = torch.rand(512, generator=gen, dtype=torch.float64) * total
    mass[-1] = total * 1.01  # past the total: one past the extent, clamped by the sampler
    every = torch.searchsorted(tree.values.cumsum(0), mass[:-1], right=True)
    found = tree.scan_lower_bound(mass)
    assert torch.equal(found[:-1], every) and found[-1] == 2_500
    restored = FlatPriorityTree(100_000, "sum", torch.float64)
    restored.values = tree.values.clone()
    assert restored.extent == 2_500
    assert FlatPriorityTree(10, "min", torch.float32).extent == 0


def test_a_tree_without_host_reads_answers_as_one_with_them():
    """A GPU's trees (``host_reads=False``, run here on the CPU): tensor-bounded queries stay
    tensors and equal the float answers, the search over every slot finds what the search over
    the written extent finds, and a GPU tree read back onto the CPU reads the host again."""
    from gentlerl.data.prioritized import FlatPriorityTree

    gen = torch.Generator().manual_seed(1)
    values = torch.rand(300, generator=gen, dtype=torch.float64)
    for reduce in ("sum", "min"):
        host = FlatPriorityTree(1_000, reduce, torch.float64)
        free = FlatPriorityTree(1_000, reduce, torch.float64, host_reads=False)
        for tree in (host, free):
            tree[torch.arange(300)] = values
        assert host.extent == 300 and free.extent == 1_000
        for left, right in ((0, 300), (17, 211), (0, 1_000)):
            got = free.query(torch.tensor(left), torch.tensor(right))
            assert isinstance(got, torch.Tensor) and got.ndim == 0
            assert float(got) == pytest.approx(host.query(left, right), rel=1e-12)
        assert free.query(0, 300) == pytest.approx(host.query(0, 300), rel=1e-12)
    mass = torch.rand(256, generator=gen, dtype=torch.float64) * float(values.sum())
    assert torch.equal(free_scan := _sum_tree(values, False).scan_lower_bound(mass),
                       _sum_tree(values, True).scan_lower_bound(mass))  # fmt: skip
    assert int(free_scan.max()) < 300
    moved = free.to("cpu")  # a GPU tree read back onto the CPU: host reads, its extent found
    assert moved.host_reads and moved.extent == 300 and torch.equal(moved.values, free.values)


def _sum_tree(values: torch.Tensor, host_reads: bool):
    from gentlerl.data.prioritized import FlatPriorityTree

    tree = FlatPriorityTree(1_000, "sum", torch.float64, host_reads=host_reads)
    tree[torch.arange(len(values))] = values
    return tree


def test_the_sampler_with_trees_that_make_no_host_reads_samples_as_with_them():
    """TorchRL's sampler logic over trees that answer with tensors (as on a GPU): the same seed
    draws the same indices and importance weights as over the host-reading trees."""
    from gentlerl.data.prioritized import FlatPriorityTree

    draws = []
    for host_reads in (True, False):
        torch.manual_seed(0)
        np.random.seed(0)
        rb = make_replay_buffer(64, 32, n_steps=1, alpha=0.6, beta=0.4)
        sampler = rb._sampler
        for name in ("_sum_tree", "_min_tree"):
            reduce = "sum" if name == "_sum_tree" else "min"
            tree = FlatPriorityTree(64, reduce, sampler.dtype, host_reads=host_reads)
            setattr(sampler, name, tree)
        rb.extend(_trajectory(T=20, terminal_at=19))
        td = rb[:]
        td[keys.PRIORITY] = torch.linspace(0.1, 3.0, len(td))
        td["index"] = torch.arange(len(td))
        rb.update_tensordict_priority(td)
        batch = rb.sample()
        draws.append((batch["index"], batch["priority_weight"]))
    assert torch.equal(draws[0][0], draws[1][0])
    torch.testing.assert_close(draws[0][1], draws[1][1])
    tree_values = (torch.linspace(0.1, 3.0, len(td)) + 1e-8) ** 0.6  # (p + eps)^alpha
    expected = (tree_values[draws[1][0]] / tree_values.min()) ** -0.4  # (p_i / p_min)^-beta
    torch.testing.assert_close(draws[1][1], expected.to(draws[1][1].dtype))
