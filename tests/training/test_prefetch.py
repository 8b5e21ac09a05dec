"""Collection overlapped with learning: one batch of policy lag, own noise stream, same results."""

import time

import pytest
import torch
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.models import make_exploration_policy
from gentlerl.training import train
from gentlerl.training.prefetch import PrefetchCollector, snapshot_policy
from tests.helpers import read_scalar, tiny_config, toy_env
from tests.toy_env import ToyHandEnv


def _constant_actor() -> TensorDictModule:
    """action = bias (the weights are zero), so a batch's actions show the weights it ran with."""
    linear = torch.nn.Linear(63, 20)
    torch.nn.init.zeros_(linear.weight)
    torch.nn.init.zeros_(linear.bias)
    return TensorDictModule(
        torch.nn.Sequential(linear, torch.nn.Tanh()), ["observation"], ["action"]
    )


def _actions_while_training(collector, actor) -> list[list[float]]:
    """Each batch's distinct first action dims, the learner's actor moved after every batch (its
    bias to 0.1 x k after batch k - 1); the collector is shut down at the end."""
    seen = []
    for k, batch in enumerate(collector):
        seen.append(batch[keys.ACTION][:, 0].unique().tolist())
        with torch.no_grad():  # "training" on batch k moves the learner's actor
            actor.module[0].bias.fill_(0.1 * (k + 1))
    collector.shutdown()
    return seen


def test_batch_k_is_collected_with_the_weights_after_training_on_batch_k_minus_2():
    actor = _constant_actor()
    policy = make_exploration_policy(actor, sigma=0.0, action_dim=20)
    collector = PrefetchCollector(
        lambda p: Collector(
            ToyHandEnv,
            p,
            frames_per_batch=10,
            total_frames=60,
            auto_register_policy_transforms=False,
        ),
        policy,
    )
    seen = _actions_while_training(collector, actor)
    expected = [0.0, 0.0, 0.1, 0.2, 0.3, 0.4]
    assert [len(s) for s in seen] == [1] * 6
    torch.testing.assert_close(
        torch.tensor([s[0] for s in seen]), torch.tanh(torch.tensor(expected))
    )
    # The learner's actor is not the collector's: that one holds the last weights synced (0.5).
    assert actor.module[0].bias[0].item() == pytest.approx(0.6)
    assert collector.policy[0].module[0].bias[0].item() == pytest.approx(0.5)


def test_noise_has_its_own_stream_and_ignores_the_exploration_type():
    policy = snapshot_policy(make_exploration_policy(_constant_actor(), sigma=0.3, action_dim=20))
    td = ToyHandEnv().reset()
    policy[1].generator.manual_seed(4)
    torch.manual_seed(0)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        first = policy(td.clone())[keys.ACTION]
    policy[1].generator.manual_seed(4)
    torch.manual_seed(1)  # the global stream does not matter
    second = policy(td.clone())[keys.ACTION]
    assert torch.equal(first, second) and first.abs().max() > 0.05


def test_overlapped_runs_repeat_exactly(tmp_path):
    for name in ("first", "again"):
        train(tiny_config(tmp_path / name, total_frames=400, overlap=True), toy_env)
    for name in ("train/loss_value", "train/model_penalty", "eval/success_rate"):
        first = read_scalar(tmp_path / "first", name)
        assert first and read_scalar(tmp_path / "again", name) == first, name


class _SlowToyEnv(ToyHandEnv):
    """The toy env, each step ``delay`` s longer: the same data, collected on another timing."""

    def __init__(self, delay: float) -> None:
        super().__init__(time_limit=50)
        self.delay = delay

    def _step(self, tensordict):
        time.sleep(self.delay)
        return super()._step(tensordict)


def test_an_overlapped_run_does_not_depend_on_how_long_collection_takes(tmp_path):
    """The random frames' actions come from the global generator, which the learner's side
    (replay and model batches) draws from too: collected beside it, their order would follow the
    threads' timing. A slow env must give the run of a fast one."""
    for name, delay in (("fast", 0.0), ("slow", 0.002)):
        cfg = tiny_config(tmp_path / name, total_frames=400, overlap=True)
        train(cfg, lambda delay=delay: _SlowToyEnv(delay))
    for name in ("train/loss_value", "train/model_penalty"):
        fast = read_scalar(tmp_path / "fast", name)
        assert fast and read_scalar(tmp_path / "slow", name) == fast, name
