"""SeedRun: what a checkpoint's checks read of one seed's run, every member of which a Trainer
(its one implementation) holds."""

from gentlerl.training import Trainer
from gentlerl.training.seed_run import SeedRun
from tests.helpers import tiny_config, toy_env


def test_a_trainer_holds_every_member_a_seed_run_declares(tmp_path):
    trainer = Trainer(tiny_config(tmp_path, total_frames=300), toy_env)
    members = set(SeedRun.__annotations__) | {n for n in vars(SeedRun) if not n.startswith("_")}
    assert {"learner", "rewards", "beta_schedule", "loss"} <= members
    assert [name for name in sorted(members) if not hasattr(trainer, name)] == []
    assert trainer.policy is trainer.learner.policy_of(trainer.seat)
    assert trainer.loss is trainer.learner.losses[trainer.seat]
