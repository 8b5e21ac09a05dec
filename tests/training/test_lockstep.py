"""Lockstep: the loop's driver over one seed's run or several, each update one step of all."""

import pytest
import torch

from gentlerl.models.stacking import SeedStack
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


def test_a_group_builds_each_stack_once_for_its_seeds_and_no_seed_its_own(tmp_path, monkeypatch):
    built = []
    init = SeedStack.__init__

    def counted(self, per_seed, *args, **kwargs):
        built.append(len(per_seed))
        init(self, per_seed, *args, **kwargs)

    monkeypatch.setattr(SeedStack, "__init__", counted)
    trainers = [Trainer(tiny_config(tmp_path / f"s{s}", seed=s), toy_env) for s in (0, 1)]
    assert built == []  # the seeds' learners and model steps are not built on their own
    loop = Lockstep(trainers)
    assert built == [2] * (1 + len(loop.models)) and len(loop.models) >= 1


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


def test_one_run_dir_twice_is_refused_and_a_lockstep_holds_its_run_locks(tmp_path):
    """The findings: ``Lockstep`` (public) took no run lock and did not check that its run dirs
    differ: one run dir twice duplicated eval rows and one checkpoint overwrote the other."""
    from gentlerl.training.run_lock import RunLock, held_here

    twice = [
        Trainer(tiny_config(tmp_path / "a", seed=s, total_frames=300), toy_env) for s in (0, 1)
    ]
    with pytest.raises(ValueError, match=r"each seed needs its own run_dir, got \['.*a', '.*a'\]"):
        Lockstep(twice)
    with pytest.raises(ValueError, match="each seed needs its own run_dir"):
        Lockstep([twice[0], twice[0]])
    assert list((tmp_path / "a").iterdir()) == []  # nothing written
    trainer = Trainer(tiny_config(tmp_path / "b", total_frames=300), toy_env)
    with RunLock(tmp_path / "b"):  # another writer (here: this process, as a second run would be)
        seen = []
        loop = Lockstep([trainer])
        loop._run = lambda: seen.append(held_here(tmp_path / "b")) or []
        assert loop.run() == [] and seen == [True]  # its caller's lock kept, not taken twice
    loop = Lockstep([trainer])
    loop._run = lambda: seen.append(held_here(tmp_path / "b")) or []
    loop.run()
    assert seen == [True, True] and not held_here(tmp_path / "b")  # taken for the run, released
    with RunLock(tmp_path / "c"):
        import multiprocessing

        child = multiprocessing.get_context("fork").Process(
            target=lambda: Lockstep(
                [Trainer(tiny_config(tmp_path / "c", total_frames=300), toy_env)]
            ).run()
        )
        child.start()
        child.join(120)
        assert child.exitcode == 1  # RunLockedError in the other process: nothing run
