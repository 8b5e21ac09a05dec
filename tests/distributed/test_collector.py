"""collector=ray: 2 remote collectors on a local Ray feed the learner; resume; worker errors."""

import os
import subprocess
import sys
from functools import partial
from pathlib import Path

import pytest

from gentlerl.training import Trainer, load_checkpoint, make_config
from tests.helpers import read_scalar, tiny_config
from tests.toy_env import ToyHandEnv

ray = pytest.importorskip("ray")
ROOT = Path(__file__).resolve().parents[2]


class FailingToyEnv(ToyHandEnv):
    """Raises on its ``fail_after``-th step (counted over the worker's whole life)."""

    def __init__(self, fail_after: int):
        super().__init__(time_limit=50)
        self.fail_after, self.steps = fail_after, 0

    def _step(self, tensordict):
        self.steps += 1
        if self.steps == self.fail_after:
            raise RuntimeError(f"worker env broke at its step {self.steps}")
        return super()._step(tensordict)


def ray_config(run_dir, **overrides):
    values = dict(
        kind="ray", num_workers=2, total_frames=600, checkpoint_every_frames=200,
        eval_every_frames=600, eval_episodes=1, weight_sync_every=10,
    )  # fmt: skip
    return tiny_config(run_dir, **{**values, **overrides})


def _ray_processes(marker: str) -> list[int]:
    """Live processes whose environment holds ``marker`` (Ray's head, raylet and workers do)."""
    pids = []
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            if marker.encode() in environ.read_bytes():
                pids.append(int(environ.parent.name))
        except OSError:  # exited, or not ours
            continue
    return [p for p in pids if p != os.getpid()]


@pytest.mark.slow
def test_the_recipe_trains_the_hand_env_with_2_ray_workers_and_leaves_no_ray_processes(tmp_path):
    # Its own Ray (started and stopped by the recipe), tagged to find its processes afterwards.
    marker = f"GENTLERL_RAY_TEST={tmp_path.name}"
    env = {**os.environ, marker.split("=")[0]: tmp_path.name, "PYTHONPATH": str(ROOT / "src")}
    overrides = [
        "collector.kind=ray", "collector.num_workers=2", "collector.total_frames=400",
        "collector.frames_per_batch=100", "collector.init_random_frames=200",
        "replay.batch_size=16", "logging.eval_episodes=1", "logging.eval_every_frames=400",
        "logging.checkpoint_every_frames=200", "network.actor_hidden=[16]",
        "network.critic_hidden=[16]", "gentleness.model_hidden=8", "logging.wandb_mode=disabled",
        "logging.progress=false", f"run_dir={tmp_path / 'run'}",
    ]  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-m", "gentlerl", "train", *overrides],
        env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "run" / "DONE").exists()
    assert load_checkpoint(tmp_path / "run" / "checkpoint.pt")["counters"]["frames"] == 400
    assert _ray_processes(marker) == []


@pytest.fixture(scope="module")
def local_ray():
    """One small local Ray for the module (starting one costs seconds)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_two_ray_workers_train_on_the_toy_env(local_ray, tmp_path):
    trainer = Trainer(ray_config(tmp_path, total_frames=400), partial(ToyHandEnv, time_limit=50))
    summary = trainer.run()
    # 2 workers x 50 steps per batch, 4 batches; utd 0.5 after 200 random frames: 100 updates.
    assert trainer.counters == {"frames": 400, "updates": 100, "update_credit": 0.0}
    assert [s for s, _ in read_scalar(tmp_path, "train/loss_value")] == [300, 400]
    assert (tmp_path / "DONE").exists() and 0.0 <= summary["success_rate"] <= 1.0
    # The workers' episodes (time limit 50) were logged by the learner: 2 x 400 / 2 / 50 = 8.
    assert len(read_scalar(tmp_path, "episode/length")) == 8


@pytest.mark.slow
def test_a_worker_error_reaches_the_learner_with_its_traceback_and_the_run_resumes(
    local_ray, tmp_path
):
    # Each worker collects 50 steps per batch: step 160 breaks the 4th batch (frames 301-400),
    # after the checkpoint at 200 frames.
    trainer = Trainer(ray_config(tmp_path), partial(FailingToyEnv, fail_after=160))
    with pytest.raises(Exception, match="worker env broke at its step 160") as err:
        trainer.run()
    assert "Traceback" in str(err.value) and "in _step" in str(err.value)
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    assert state["counters"]["frames"] == 200 and not (tmp_path / "DONE").exists()
    # Resumed from that checkpoint with new workers, to the end.
    resumed = Trainer(ray_config(tmp_path, resume=True), partial(ToyHandEnv, time_limit=50))
    resumed.run()
    assert resumed.counters == {"frames": 600, "updates": 200, "update_credit": 0.0}
    assert [s for s, _ in read_scalar(tmp_path, "train/loss_value")] == [300, 400, 500, 600]


def test_bad_ray_settings_are_clear_errors():
    def config(**collector):
        return make_config(collector={"kind": "ray", **collector})

    with pytest.raises(ValueError, match="100 must be a multiple of collector.num_workers=3"):
        config(num_workers=3, frames_per_batch=100)
    with pytest.raises(ValueError, match=r"collector.cpus_per_worker=0 must be in \(0, 256\]"):
        config(cpus_per_worker=0)
    with pytest.raises(ValueError, match="collector.num_envs=2 with collector.kind=ray"):
        config(num_envs=2)
    with pytest.raises(ValueError, match="port 'x' is not a number"):
        config(ray_address="ray://head:x")


def test_ray_problems_split_a_batch_evenly_and_keep_the_address_to_kind_ray():
    from gentlerl.config.groups import CollectorConfig
    from gentlerl.distributed.collector import ray_problems

    ok = CollectorConfig(kind="ray", num_workers=4, frames_per_batch=100)
    assert ray_problems(ok) == []
    uneven = ray_problems(CollectorConfig(kind="ray", num_workers=3, frames_per_batch=100))
    assert len(uneven) == 1
    assert uneven[0].startswith(
        "collector.frames_per_batch=100 must be a multiple of collector.num_workers=3"
    )
    # the same split is no problem for the multi-process collector
    assert ray_problems(CollectorConfig(kind="multi", num_workers=3, frames_per_batch=100)) == []
    stray = ray_problems(CollectorConfig(kind="single", ray_address="auto"))
    assert len(stray) == 1 and "applies to collector.kind=ray only" in stray[0]
