"""Loggers (csv, wandb, tensorboard through TorchRL's get_logger), the progress bar, and
checkpoints without the replay buffers."""

import math

import pytest
import torch

from gentlerl.config.layout import CHECKPOINT
from gentlerl.training import make_config
from gentlerl.training.checkpoint import load_checkpoint
from gentlerl.training.logging import RunLogger, progress_postfix
from gentlerl.training.loop import Trainer, train
from tests.helpers import read_scalar, tiny_config, toy_env


def test_csv_only_by_default_and_wandb_offline_and_silent_when_asked(tmp_path, capfd):
    assert make_config().logging.logger == "csv"
    assert len(RunLogger(tmp_path / "csv", {}).loggers) == 1  # the default writes CSV only
    assert not (tmp_path / "csv" / "wandb").exists()
    logging = {"logger": "wandb", "wandb_mode": "offline", "eval_episodes": 1}
    train(tiny_config(tmp_path / "wb", logging=logging, collector={"total_frames": 300}), toy_env)
    (run,) = (tmp_path / "wb" / "wandb").glob("offline-run-*")
    assert list(run.glob("*.wandb"))  # the run's records, ready for `wandb sync`
    out = capfd.readouterr()
    assert "wandb" not in out.out + out.err  # no banner, no summary block
    assert read_scalar(tmp_path / "wb", "eval/success_rate")  # CSV is always written


def test_tensorboard_logger_writes_the_same_scalars(tmp_path):
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    logging = {"logger": "tensorboard", "eval_episodes": 1}
    train(tiny_config(tmp_path, logging=logging, collector={"total_frames": 300}), toy_env)
    (events,) = (tmp_path / "tensorboard").rglob("events.out.tfevents.*")
    board = EventAccumulator(str(events.parent)).Reload()
    logged = [(e.step, round(e.value, 5)) for e in board.Scalars("eval/success_rate")]
    assert logged == [(s, round(v, 5)) for s, v in read_scalar(tmp_path, "eval/success_rate")]
    assert [s for s, _ in logged] == [300]  # the final evaluation


def test_an_unknown_logger_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="logger='mlflow' is not one of"):
        make_config(logging={"logger": "mlflow"})
    with pytest.raises(ValueError, match="logger must be one of csv, wandb, tensorboard"):
        RunLogger(tmp_path, {}, logger="mlflow")


def test_progress_bar_shows_one_speed(tmp_path):
    trainer = Trainer(tiny_config(tmp_path), toy_env)
    history = trainer.state.eval_history
    assert set(progress_postfix([], history)) == {"success", "max_impact", "eval"}


def test_checkpoint_without_buffers_is_smaller_and_resumes(tmp_path):
    sizes = {}
    for keep in (True, False):
        run_dir = tmp_path / str(keep)
        logging = {"checkpoint_buffer": keep}
        train(tiny_config(run_dir, logging=logging, collector={"total_frames": 400}), toy_env)
        sizes[keep] = (run_dir / CHECKPOINT).stat().st_size
    state = load_checkpoint(tmp_path / "False" / CHECKPOINT)
    assert state["rb"] is None and state["model_rb"] is None and state["nstep"] is None
    assert sizes[False] < sizes[True] / 2, sizes  # 400 transitions x 2 buffers dominate
    longer = tiny_config(
        tmp_path / "False",
        logging={"checkpoint_buffer": False},
        collector={"total_frames": 600},
        resume=True,
    )
    resumed = Trainer(longer, toy_env)
    resumed.run()
    assert resumed.counters["frames"] == 600
    assert len(resumed.rewards.buffer) == 200  # refilled from the resume on: 200 new frames
    assert torch.isfinite(torch.tensor(read_scalar(tmp_path / "False", "eval/success_rate"))).all()


def test_a_nan_impact_beside_a_9_newton_peak_is_logged_as_nan_not_as_the_other_steps():
    """An episode's max impact with a NaN step is NaN (seen), not the max of its finite steps
    nor 0 N: python's max(0.0, nan) is 0.0, which hid the 9 N peak of the batch."""
    from tensordict import TensorDict

    from gentlerl import keys
    from gentlerl.training.logging import EpisodeStats

    def batch(impacts, done):
        n = len(impacts)
        nxt = {
            keys.REWARD: torch.zeros(n, 1),
            keys.IMPACT: torch.tensor(impacts).reshape(n, 1),
            keys.DONE: torch.tensor(done).reshape(n, 1),
            "step_count": torch.arange(1, n + 1).reshape(n, 1),
            "episode_reward": torch.zeros(n, 1),
        }
        return TensorDict(
            {("collector", "traj_ids"): torch.zeros(n, dtype=torch.int64), "next": nxt}, [n]
        )

    tracker = EpisodeStats([keys.REWARD])
    (episode,) = tracker.update(batch([9.0, float("nan"), 0.5], [False, False, True]))
    assert math.isnan(episode["max_impact"])
    tracker.update(batch([float("nan"), 1.0], [False, False]))  # the NaN in an earlier batch
    (episode,) = tracker.update(batch([9.0], [True]))
    assert math.isnan(episode["max_impact"])
