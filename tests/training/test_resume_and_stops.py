"""Run guards: what resume accepts, the config history, finished runs, the final evaluation logged
once, and the stop at the first non-finite reward or loss."""

import shutil
from pathlib import Path

import pytest
import torch
import yaml

from gentlerl import keys
from gentlerl.training import Trainer, load_checkpoint, train
from gentlerl.training.resume import config_changes
from gentlerl.training.stops import NonFiniteError, stop_if_not_finite
from tests.helpers import read_scalar, tiny_config, toy_env
from tests.toy_env import ToyHandEnv

#: One evaluation and one checkpoint, both at the end (frame 300).
SHORT = dict(total_frames=300, eval_every_frames=300, checkpoint_every_frames=300, eval_episodes=2)


@pytest.fixture(scope="module")
def done_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("done") / "run"
    summary = train(tiny_config(run_dir, **SHORT), toy_env)
    return run_dir, summary


def _copy(done_run, tmp_path) -> Path:
    run_dir = tmp_path / "run"
    shutil.copytree(done_run[0], run_dir)
    return run_dir


def _eval_rows(run_dir: Path) -> list[str]:
    return (run_dir / "eval_episodes.csv").read_text().splitlines()[1:]


def test_the_final_evaluation_is_logged_once(done_run):
    run_dir, summary = done_run
    # The last batch reaches eval_every_frames: that evaluation is the final one, not a second.
    assert [step for step, _ in read_scalar(run_dir, "eval/success_rate")] == [300]
    assert len(_eval_rows(run_dir)) == 2
    assert summary["success_rate"] == read_scalar(run_dir, "eval/success_rate")[0][1]


def test_resume_true_without_a_checkpoint_is_an_error_and_writes_nothing(tmp_path):
    with pytest.raises(ValueError, match="resume=true but there is no checkpoint to resume at"):
        Trainer(tiny_config(tmp_path / "new", resume=True), toy_env)
    assert not (tmp_path / "new").exists()


def test_a_finished_run_is_not_run_again(done_run, tmp_path):
    run_dir = _copy(done_run, tmp_path)
    before = {p.name: p.read_bytes() for p in run_dir.rglob("*") if p.is_file()}
    for resume in (True, "auto"):
        summary = train(tiny_config(run_dir, **SHORT, resume=resume), toy_env)
        assert summary == done_run[1]
    assert {p.name: p.read_bytes() for p in run_dir.rglob("*") if p.is_file()} == before


def test_structural_changes_are_one_line_listing_them(done_run, tmp_path):
    run_dir = _copy(done_run, tmp_path)
    config = (run_dir / "config.yaml").read_text()
    changed = tiny_config(run_dir, **SHORT, resume=True, seed=5, actor_hidden=(16,), variant="r+rf")
    with pytest.raises(ValueError) as err:
        Trainer(changed, toy_env)
    message = str(err.value)
    assert "\n" not in message and "structural settings differ" in message
    for name in ("network.actor_hidden ([32, 32] -> [16])", "seed (0 -> 5)", "variant ("):
        assert name in message
    assert (run_dir / "config.yaml").read_text() == config


def test_safe_changes_continue_the_run_and_are_recorded(done_run, tmp_path):
    run_dir = _copy(done_run, tmp_path)
    cfg = tiny_config(run_dir, **{**SHORT, "total_frames": 400}, resume="auto", batch_size=16)
    trainer = Trainer(cfg, toy_env)
    trainer.run()
    assert trainer.counters["frames"] == 400 and (run_dir / "DONE").exists()
    (entry,) = yaml.safe_load((run_dir / "config_history.yaml").read_text())
    assert entry == {
        "resumed_at_frame": 300,
        "changed": {
            "collector.total_frames": {"was": 300, "now": 400},
            "replay.batch_size": {"was": 32, "now": 16},
        },
    }
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["replay"]["batch_size"] == 16


def test_resume_auto_starts_a_run_that_does_not_exist(tmp_path):
    cfg = tiny_config(tmp_path / "fresh", **{**SHORT, "total_frames": 200}, resume="auto")
    trainer = Trainer(cfg, toy_env)
    trainer.run()
    assert (
        trainer.counters["frames"] == 200 and not (tmp_path / "fresh/config_history.yaml").exists()
    )


class _NaNTouchEnv(ToyHandEnv):
    """The toy env whose touch sensor reads NaN from its 130th step on."""

    steps = 0

    def _step(self, tensordict):
        out = super()._step(tensordict)
        _NaNTouchEnv.steps += 1
        if _NaNTouchEnv.steps >= 130:
            out[keys.TOUCH][0, 0] = float("nan")
        return out


def test_training_stops_at_the_first_non_finite_reward_keeping_the_checkpoint(tmp_path):
    _NaNTouchEnv.steps = 0
    cfg = tiny_config(tmp_path, total_frames=400, checkpoint_every_frames=100)
    with pytest.raises(NonFiniteError) as err:
        train(cfg, lambda: _NaNTouchEnv(time_limit=50))
    message = str(err.value)
    assert message.startswith("non-finite force at frames 101-200: training stopped")
    assert "'touch' holds a non-finite force (nan) at s_t, index [29], site 0" in message
    assert f"the last checkpoint {tmp_path / 'checkpoint.pt'} is intact" in message
    assert load_checkpoint(tmp_path / "checkpoint.pt")["counters"]["frames"] == 100
    assert not (tmp_path / "DONE").exists()


def test_a_non_finite_loss_names_itself_and_where():
    stop_if_not_finite({"loss_actor": 1.5, "reward": torch.ones(3)}, "frame 9", Path("/nope"))
    with pytest.raises(NonFiniteError, match=r"non-finite loss_value at frame 9 \(update 3\)"):
        stop_if_not_finite({"loss_value": float("inf")}, "frame 9 (update 3)", Path("/nope"))
    with pytest.raises(NonFiniteError, match="no checkpoint was written yet"):
        stop_if_not_finite({"reward": torch.tensor([0.0, float("nan")])}, "x", Path("/nope"))


def test_config_changes_compare_leaves_with_tuples_as_lists():
    saved = {"seed": 0, "network": {"actor_hidden": [32, 32]}, "env": {"kwargs": {"a": 1}}}
    now = {"seed": 0, "network": {"actor_hidden": (32, 32)}, "env": {"kwargs": {"a": 2}}}
    assert config_changes(saved, now) == {"env.kwargs": ({"a": 1}, {"a": 2})}


def test_a_refused_command_line_run_leaves_no_run_dir(tmp_path):
    # hydra makes no folder; the trainer makes run_dir (and its parents) only once the config
    # and the env are checked, and removes what it made when a resume is refused.
    from gentlerl.cli import main

    run_dir = tmp_path / "a" / "refused"
    with pytest.raises(SystemExit, match="resume=true but there is no checkpoint"):
        main(["train", f"run_dir={run_dir}", "resume=true"])
    assert list(tmp_path.iterdir()) == []


def test_a_checkpoint_older_than_a_field_resumes_with_the_behaviour_of_its_time(done_run, tmp_path):
    """A run saved before dense supports and recomputed surprise (its config lacks both) trained
    with a shared support and stored r^sp: resuming with those values is no structural change;
    today's defaults are one, named."""
    from gentlerl.training.checkpoint import save_checkpoint

    run_dir = _copy(done_run, tmp_path)
    ckpt = run_dir / "checkpoint.pt"
    state = load_checkpoint(ckpt)
    del state["config"]["network"]["dense_reward_bound"]
    del state["config"]["gentleness"]["rescore_surprise"]
    del state["supports"]
    save_checkpoint(ckpt, state)
    with pytest.raises(ValueError, match=r"network.dense_reward_bound \(None -> 1.0\)"):
        Trainer(tiny_config(run_dir, **SHORT, resume=True), toy_env)
    earlier = tiny_config(run_dir, **SHORT, resume=True)
    earlier.network.dense_reward_bound = None
    earlier.gentleness.rescore_surprise = False
    assert Trainer(earlier, toy_env).learner.loss.value_network.module.v_min == (-10.0,) * 3
