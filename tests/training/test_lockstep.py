"""Lockstep: the loop's driver over one seed's run or several, each update one step of all."""

import pytest
import torch

from gentlerl.training import Lockstep, Trainer
from tests.helpers import read_scalar, tiny_config, toy_env


def test_one_seed_uses_its_own_learner_and_model_steps(tmp_path):
    """S = 1: nothing is rebuilt; the update steps the trainer's own learner and models."""
    trainer = Trainer(tiny_config(tmp_path, total_frames=300), toy_env)
    own_learner, own_steps = trainer.learner, trainer.rewards.steps
    loop = Lockstep([trainer])
    assert loop.learner is own_learner and trainer.seat == 0
    assert loop.models == own_steps and all(s.num_seeds == 1 for s in own_steps.values())
    summary = loop.run()[0]
    assert "success_rate" in summary and trainer.counters["updates"] == 50
    assert [f for f, _ in read_scalar(tmp_path, "train/loss_value")] == [300]  # every 50 updates


def test_several_seeds_share_one_learner_and_one_step_per_model_each_its_own_row(tmp_path):
    trainers = [
        Trainer(tiny_config(tmp_path / f"seed{s}", seed=s, total_frames=300), toy_env)
        for s in (0, 1, 2)
    ]
    losses = [t.loss for t in trainers]
    loop = Lockstep(trainers)
    assert loop.learner.num_seeds == 3 and [t.seat for t in trainers] == [0, 1, 2]
    assert all(t.learner is loop.learner for t in trainers)
    assert loop.learner.losses == losses  # each seed's own loss, its row of the stack
    for name, step in loop.models.items():
        assert step.num_seeds == 3
        assert all(t.rewards.steps[name] is step for t in trainers)
    loop.run()
    for s, trainer in enumerate(trainers):
        row = loop.learner.params["actor"][s]
        own = trainer.loss.actor_network_params
        for key, value in own.items(True, True):
            assert torch.equal(value, row[key])  # no copy: the seed's tensors read its row


def test_a_lockstep_is_refused_without_seeds_or_with_checkpoints_at_different_frames(tmp_path):
    with pytest.raises(ValueError, match="Lockstep needs at least one Trainer"):
        Lockstep([])
    for s, frames in ((0, 300), (1, 400)):
        Trainer(tiny_config(tmp_path / f"seed{s}", seed=s, total_frames=frames), toy_env).run()
        (tmp_path / f"seed{s}" / "DONE").unlink()
    resumed = [
        Trainer(tiny_config(tmp_path / f"seed{s}", seed=s, total_frames=500, resume=True), toy_env)
        for s in (0, 1)
    ]
    with pytest.raises(ValueError, match=r"checkpoints are at different frames \[300, 400\]"):
        Lockstep(resumed)
