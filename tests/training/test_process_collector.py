"""Collection in a child process: one batch of policy lag, batches in order and time-contiguous,
the thread's batches, repeatable runs, no process left behind."""

import multiprocessing
from functools import partial

import pytest
import torch
from torchrl.collectors import Collector
from torchrl.envs import SerialEnv

from gentlerl import keys
from gentlerl.models import make_exploration_policy
from gentlerl.training import Trainer, make_config
from gentlerl.training.prefetch import PrefetchCollector
from gentlerl.training.process_collector import ProcessCollector
from tests.helpers import read_scalar, tiny_config, toy_env
from tests.toy_env import ToyHandEnv
from tests.training.test_prefetch import _actions_while_training, _constant_actor


def _collector(env=ToyHandEnv, frames_per_batch=10, total_frames=60, **kwargs) -> partial:
    """A picklable ``make_collector`` for the toy env."""
    return partial(
        Collector,
        env,
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        auto_register_policy_transforms=False,
        **kwargs,
    )


def _two_hands() -> SerialEnv:
    return SerialEnv(2, ToyHandEnv)


def _no_children_left() -> bool:
    return not multiprocessing.active_children()


def test_batch_k_is_collected_with_the_weights_after_training_on_batch_k_minus_2():
    actor = _constant_actor()
    policy = make_exploration_policy(actor, sigma=0.0, action_dim=20)
    collector = ProcessCollector(_collector(), policy)
    seen = _actions_while_training(collector, actor)
    assert [len(s) for s in seen] == [1] * 6
    expected = torch.tanh(torch.tensor([0.0, 0.0, 0.1, 0.2, 0.3, 0.4]))
    torch.testing.assert_close(torch.tensor([s[0] for s in seen]), expected)
    assert _no_children_left()


def test_batches_come_in_order_and_each_row_is_time_contiguous():
    policy = make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20)
    collector = ProcessCollector(
        _collector(_two_hands, frames_per_batch=20, total_frames=120), policy
    )
    collector.set_seed(1)
    batches = list(collector)
    collector.shutdown()
    assert [b.shape for b in batches] == [torch.Size([2, 10])] * 6
    rows = torch.cat(batches, dim=1)  # [2, 60]: each row one env's steps in order
    goes_on = ~rows["next", keys.DONE][:, :-1, 0]  # step t + 1 continues step t's episode
    after = rows[keys.OBSERVATION][:, 1:][goes_on]
    assert torch.equal(after, rows["next", keys.OBSERVATION][:, :-1][goes_on])
    episodes = rows["collector", "traj_ids"]
    assert (episodes[:, 1:] >= episodes[:, :-1]).all()
    assert not goes_on.all(), "episodes of 50 steps end within 60"


def test_the_process_collects_the_threads_batches_and_repeats_them():
    def batches(kind, seed):
        policy = make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20)
        collector = kind(_collector(), policy, seed)
        collector.set_seed(seed)
        out = [b.exclude("collector") for b in collector]
        collector.shutdown()
        return out

    process = batches(ProcessCollector, 3)
    for other in (batches(ProcessCollector, 3), batches(PrefetchCollector, 3)):
        assert all((a == b).all() for a, b in zip(process, other, strict=True))
    assert not (batches(ProcessCollector, 4)[0] == process[0]).all()


def test_random_frames_repeat_with_the_seed():
    def first_batch(seed):
        policy = make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20)
        collector = ProcessCollector(_collector(init_random_frames=20), policy, seed)
        collector.set_seed(seed)
        batch = next(iter(collector))
        collector.shutdown()  # with the next batch asked for and not taken
        assert _no_children_left()
        return batch[keys.ACTION]

    assert torch.equal(first_batch(2), first_batch(2))
    assert not torch.equal(first_batch(2), first_batch(3))


def _failing_env():
    raise ValueError("no hand here")


def test_a_failing_env_raises_here_and_leaves_no_process():
    policy = make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20)
    with pytest.raises(RuntimeError, match="no hand here"):
        ProcessCollector(_collector(_failing_env), policy)
    assert _no_children_left()


def test_training_with_the_process_collector_repeats_exactly(tmp_path):
    for name in ("first", "again"):
        cfg = tiny_config(tmp_path / name, total_frames=400, overlap="process")
        trainer = Trainer(cfg, toy_env)
        trainer.run()
        assert trainer.counters["frames"] == 400 and trainer.counters["updates"] > 0
        assert _no_children_left()
    for name in ("train/loss_value", "train/model_penalty", "eval/success_rate"):
        first = read_scalar(tmp_path / "first", name)
        assert first and read_scalar(tmp_path / "again", name) == first, name


@pytest.mark.parametrize(
    ("collector", "problem"),
    [
        ({"overlap": "process", "kind": "multi"}, "collector.overlap=process needs"),
        ({"overlap": "thread"}, "collector.overlap='thread' must be true, false or process"),
    ],
)
def test_overlap_choices(tmp_path, collector, problem):
    with pytest.raises(ValueError, match=problem):
        make_config(run_dir=str(tmp_path), collector=collector)


@pytest.mark.parametrize(
    ("where", "error"),
    [("_receive", ConnectionResetError(104, "reset")), ("_send", BrokenPipeError(32, "broken"))],
)
def test_a_killed_child_is_named_whichever_way_the_pipe_fails(monkeypatch, where, error):
    """A child killed while it writes resets the pipe (not EOF); one killed before a request
    breaks it: both say how it ended, never a bare socket error."""
    import os
    import signal

    from gentlerl.training import process_collector
    from gentlerl.training.process_collector import CollectorDied

    policy = make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20)
    collector = ProcessCollector(_collector(), policy)
    os.kill(collector._process.pid, signal.SIGKILL)

    def fail(*args):
        raise error

    monkeypatch.setattr(process_collector, where, fail)
    with pytest.raises(CollectorDied, match="^the collector process was killed by SIGKILL$"):
        collector.set_seed(0)
    monkeypatch.undo()
    collector.shutdown()
    assert _no_children_left()
