"""Checkpoints: atomic writes, a full-state round trip, and resuming a SIGKILLed run."""

import itertools
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from gentlerl.data import make_replay_buffer
from gentlerl.models import make_actor
from gentlerl.training import Trainer, load_checkpoint, load_policy, save_checkpoint
from gentlerl.training.checkpoint import (
    CheckpointError,
    load_replay_buffer_state,
    remove_stale_temp_files,
    replay_buffer_state,
)
from tests.helpers import tiny_config, toy_env

ROOT = Path(__file__).resolve().parents[2]


def test_save_is_atomic(tmp_path):
    path = tmp_path / "checkpoint.pt"
    save_checkpoint(path, {"frames": 100, "w": torch.arange(3)})
    # pickling a local lambda fails mid-write (AttributeError on Python 3.11, PicklingError later)
    with pytest.raises((AttributeError, pickle.PicklingError), match=r"Can't pickle .*<lambda>"):
        save_checkpoint(path, {"frames": 200, "bad": lambda: None})
    state = load_checkpoint(path)
    assert state["frames"] == 100 and state["w"].tolist() == [0, 1, 2]
    assert [p.name for p in tmp_path.iterdir()] == ["checkpoint.pt"]  # no temp file left


def test_missing_checkpoint(tmp_path):
    with pytest.raises(FileNotFoundError, match="no checkpoint at"):
        load_checkpoint(tmp_path / "nope.pt")


class _Exploit:
    """Unpickling this object would run code: it creates the file ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def test_loading_runs_no_code_from_the_file(tmp_path):
    marker = tmp_path / "pwned"
    for name in ("checkpoint.pt", "best_policy.pt"):
        torch.save({"config": {}, "actor": _Exploit(marker)}, tmp_path / name)
        with pytest.raises(CheckpointError, match=name):
            load_checkpoint(tmp_path / name)
        with pytest.raises(CheckpointError, match=name):
            load_policy(tmp_path / name)
    assert not marker.exists()


@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage", "not_a_dict", "not_a_policy"])
def test_a_damaged_file_is_one_line_naming_it_and_what_to_do(tmp_path, damage):
    path = tmp_path / "checkpoint.pt"
    save_checkpoint(path, {"w": torch.randn(1000), "td": TensorDict({"a": torch.ones(3)}, [3])})
    data = path.read_bytes()
    contents = {"truncated": data[: len(data) // 2], "empty": b"", "garbage": b"\x80\x02junk" * 9}
    if damage in contents:
        path.write_bytes(contents[damage])
    elif damage == "not_a_dict":
        torch.save([1, 2], path)
    with pytest.raises(CheckpointError) as err:
        load_checkpoint(path) if damage != "not_a_policy" else load_policy(path)
    message = str(err.value)
    assert str(path) in message and "\n" not in message
    if damage in contents:
        assert "restore a good copy, or delete it" in message


def test_tensordicts_trees_and_numpy_state_survive_the_plain_format(tmp_path):
    import numpy as np

    rb = make_replay_buffer(100, 4, n_steps=1)
    rb.extend(_transitions(0, 10))
    state = {"rb": replay_buffer_state(rb), "np": np.random.RandomState(3).get_state()}
    save_checkpoint(tmp_path / "c.pt", state)
    back = load_checkpoint(tmp_path / "c.pt")
    assert (back["rb"]["_storage"]["data"] == rb[:]).all()
    assert torch.equal(back["rb"]["_sampler"]["_sum_tree"].values, rb.sampler._sum_tree.values)
    restored = np.random.RandomState()
    restored.set_state(back["np"])
    assert restored.rand() == np.random.RandomState(3).rand()


def test_stale_temp_files_of_killed_saves_are_removed(tmp_path):
    stale = [tmp_path / ".checkpoint.pt.k2j3.tmp", tmp_path / ".best_policy.pt.x9.tmp"]
    keep = [tmp_path / "checkpoint.pt", tmp_path / "notes.tmp"]
    for path in stale + keep:
        path.write_bytes(b"x")
    assert remove_stale_temp_files(tmp_path) == sorted(stale)
    assert sorted(tmp_path.iterdir()) == sorted(keep)


def _transitions(start: int, n: int) -> TensorDict:
    obs = torch.arange(start, start + n, dtype=torch.float32).unsqueeze(-1)
    flag = torch.zeros(n, 1, dtype=torch.bool)
    nxt = {"observation": obs + 1, "reward": torch.ones(n, 1), "done": flag, "terminated": flag,
           "truncated": flag}  # fmt: skip
    return TensorDict({"observation": obs, "action": obs, "next": nxt}, [n])


def test_replay_buffer_round_trip_saves_only_filled_rows(tmp_path):
    rb = make_replay_buffer(10_000, 4, n_steps=3)
    rb.extend(_transitions(0, 20))
    rb.update_priority(torch.arange(5), torch.full((5,), 7.0))
    state = replay_buffer_state(rb)
    assert state["_storage"]["data"].shape == (17,)  # 20 written, 3 wait for their window
    save_checkpoint(tmp_path / "rb.pt", state)
    save_checkpoint(tmp_path / "full.pt", rb.state_dict())  # TorchRL's: 10k pre-allocated rows
    assert (tmp_path / "rb.pt").stat().st_size < (tmp_path / "full.pt").stat().st_size / 3
    restored = make_replay_buffer(10_000, 4, n_steps=3)
    load_replay_buffer_state(restored, load_checkpoint(tmp_path / "rb.pt"))
    assert len(restored) == 17 and (restored[:] == rb[:]).all()
    assert restored.sampler._sum_tree.query(0, 17) == pytest.approx(
        rb.sampler._sum_tree.query(0, 17)
    )
    restored.extend(_transitions(100, 5))  # full capacity after loading: writes go on
    assert len(restored) == 17 + 2  # 3 of the 5 new ones wait for their window


def test_trainer_state_round_trip(tmp_path):
    run = Trainer(tiny_config(tmp_path, total_frames=500), toy_env)
    (tmp_path / ".checkpoint.pt.killed.tmp").write_bytes(b"half a checkpoint")
    run.run()
    assert not list(tmp_path.glob(".*.tmp"))  # a save killed earlier left it; run() removes it
    resumed = Trainer(tiny_config(tmp_path, total_frames=500, resume=True), toy_env)
    resumed.load_state_dict(load_checkpoint(tmp_path / "checkpoint.pt"))
    assert resumed.counters == run.counters == {"frames": 500, "updates": 150, "update_credit": 0}
    for a, b in zip(resumed.learner.loss.parameters(), run.learner.loss.parameters(), strict=True):
        assert torch.equal(a, b)
    target = "target_value_network_params"
    assert (getattr(resumed.learner.loss, target) == getattr(run.learner.loss, target)).all()
    assert resumed.learner.target_counter == run.learner.target_counter
    sa, sb = resumed.learner.optimizer.state_dict(), run.learner.optimizer.state_dict()
    assert all(
        torch.equal(sa["state"][k]["exp_avg"], sb["state"][k]["exp_avg"]) for k in sa["state"]
    )
    stored, again = run.rb[:], resumed.rb[:]  # with each transition's [5]-step window
    assert set(again.keys(True, True)) == set(stored.keys(True, True))
    assert all(torch.equal(again[k], stored[k]) for k in stored.keys(True, True))
    assert len(resumed.rewards.buffer) == 500
    for name, loss in run.rewards.losses.items():
        other = resumed.rewards.losses[name].state_dict()
        assert all(torch.equal(v, other[k]) for k, v in loss.state_dict().items())
    assert resumed.rewards.intrinsic_on == run.rewards.intrinsic_on
    assert torch.equal(torch.get_rng_state(), run.state_dict()["rng"]["torch"])
    cfg, actor = load_policy(tmp_path / "checkpoint.pt")
    assert cfg == run.cfg
    obs = TensorDict({"observation": torch.randn(7, 63)}, [7])
    assert torch.equal(actor(obs.clone())["action"], run.learner.actor(obs.clone())["action"])
    # The pending n-step tail (the last 5 steps) comes back with its last step cut (truncated).
    tail = resumed.writer.tail
    assert tail.shape == (5,) and tail["next", "truncated"][:, 0].tolist() == [0, 0, 0, 0, 1]


def test_a_checkpoint_keeps_its_critic_supports_and_refuses_others(tmp_path):
    run = Trainer(tiny_config(tmp_path, total_frames=300), toy_env)
    run.run()
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    # toy env: 50 steps; dense heads span 1 x (1 - 0.99^50) / 0.01 = 39.5; the penalty tops at 0
    assert state["supports"]["v_max"] == pytest.approx([10.0, 0.0, 39.4994], abs=1e-3)
    assert state["supports"]["v_min"] == pytest.approx([-10.0, -39.4994, -39.4994], abs=1e-3)
    resumed = Trainer(tiny_config(tmp_path, total_frames=300, resume=True), toy_env)
    state["supports"]["v_min"][1] = -100.0  # weights trained on other atoms
    with pytest.raises(ValueError, match=r"trained on supports .*dense_reward_bound"):
        resumed.load_state_dict(state)


def test_resume_to_a_longer_run_keeps_every_transition(tmp_path):
    straight = Trainer(tiny_config(tmp_path / "a", collector={"total_frames": 800}), toy_env)
    straight.run()
    train_part = Trainer(tiny_config(tmp_path / "b", collector={"total_frames": 500}), toy_env)
    train_part.run()
    resumed = Trainer(
        tiny_config(tmp_path / "b", collector={"total_frames": 800}, resume=True), toy_env
    )
    resumed.run()
    assert resumed.counters["frames"] == 800 and resumed.counters["updates"] == 300
    # 800 frames, the last 5 pending for their n-step window: same count with and without a cut.
    assert len(resumed.rb) == len(straight.rb) == 795 and len(resumed.rewards.buffer) == 800


def test_a_sigkilled_recipe_run_resumes_and_finishes(tmp_path):
    run_dir = tmp_path / "run"
    command = [
        sys.executable, "-m", "gentlerl", "train", "task=touch", "variant=r+rf",
        f"run_dir={run_dir}", "collector.total_frames=1600", "collector.frames_per_batch=100",
        "collector.init_random_frames=100", "logging.checkpoint_every_frames=300",
        "logging.eval_every_frames=100000", "logging.eval_episodes=1", "replay.batch_size=16",
        "network.actor_hidden=[16]", "network.critic_hidden=[16]", "network.num_atoms=11",
        "replay.buffer_size=5000", "gentleness.model_buffer_size=5000",
        "logging.wandb_mode=disabled", "logging.progress=false", "num_threads=1",
        "learner.utd_ratio=0.25", "+env.kwargs.time_limit=40", "collector.num_envs=4",
    ]  # fmt: skip
    env = {**os.environ, "RL_WARNINGS": "0"}
    proc = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    ckpt = run_dir / "checkpoint.pt"
    deadline = time.monotonic() + 120
    while not ckpt.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert ckpt.exists(), proc.stderr.read().decode()[-2000:]
    assert proc.returncode == -signal.SIGKILL and not (run_dir / "DONE").exists()
    killed = load_checkpoint(ckpt)
    killed_at = killed["counters"]["frames"]
    assert 300 <= killed_at < 1600
    done = subprocess.run([*command, "resume=true"], env=env, capture_output=True, timeout=180)
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    assert (run_dir / "DONE").exists()
    state = load_checkpoint(ckpt)
    assert state["counters"]["frames"] == 1600
    assert state["counters"]["updates"] == 0.25 * (1600 - 100)
    # r+rf learns no model (no 1-step buffer); all but the 5 pending frames of each of the 4 hands
    # of the collector env (collector.num_envs=4) are n-step transitions.
    assert state["model_rb"] is None
    assert len(state["rb"]["_storage"]["data"]) == 1600 - 4 * 5
    # The logs hold each frame count once: rows past the checkpoint were dropped on resume.
    steps = [
        int(r.split(",")[0]) for r in (run_dir / "logs/scalars/train/env_steps_per_s.csv").open()
    ]
    assert steps == list(range(100, 1601, 100))
    # Training wall clock goes on from the checkpoint's: it never restarts at 0 on a resume.
    walls = [float(r.split(",")[1]) for r in (run_dir / "logs/scalars/train/wall_s.csv").open()]
    assert len(walls) == len(steps) and all(b > a for a, b in itertools.pairwise(walls))
    assert walls[steps.index(killed_at)] == pytest.approx(killed["wall_s"], abs=1e-3)
    assert state["wall_s"] == pytest.approx(walls[-1], abs=1e-3)


def test_a_policy_saved_with_the_flat_config_of_older_versions_loads(tmp_path):
    actor = make_actor(63, 20, (16, 8))
    flat = dict(  # field names as older versions saved them, one level, no groups
        task="touch", variant="r+rf+rsp", seed=3, scale="cpu", collector="multi",
        env_kwargs={"time_limit": 100, "calibration": "easy"}, total_frames=5000, batch_size=64, actor_hidden=[16, 8],
        lam=[2.0, 1.0], penalty_v_max=None, wandb_project="gentlerl",
    )  # fmt: skip
    state = {"config": flat, "obs_dim": 63, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(tmp_path / "best_policy.pt", state)
    cfg, loaded = load_policy(tmp_path / "best_policy.pt")
    assert (cfg.seed, cfg.collector.kind, cfg.collector.total_frames) == (3, "multi", 5000)
    assert cfg.env.kwargs == {"time_limit": 100, "regime": "easy"}  # the regime's earlier name
    assert cfg.replay.batch_size == 64
    assert cfg.gentleness.lam == (2.0, 1.0) and cfg.network.bounded_support is False
    obs = TensorDict({"observation": torch.randn(4, 63)}, [4])
    assert torch.equal(loaded(obs.clone())["action"], actor(obs.clone())["action"])
    flat["no_such_field"] = 1
    save_checkpoint(tmp_path / "best_policy.pt", state)
    with pytest.raises(ValueError, match="unknown config field.*'no_such_field'"):
        load_policy(tmp_path / "best_policy.pt")


def _tamper_nan_reward(state):
    state["rb"]["_storage"]["data"]["next", "reward"][3] = float("nan")


def _tamper_stride_zero(state):
    data = state["rb"]["_storage"]["data"]
    data["action"] = data["action"][:1].expand_as(data["action"])


def _tamper_nan_priority(state):
    state["rb"]["_sampler"]["_sum_tree"].values[0] = float("nan")


def _tamper_negative_counter(state):
    state["counters"]["frames"] = -5


@pytest.mark.parametrize(
    ("tamper", "message"),
    [
        (_tamper_nan_reward, r"replay entry \('next', 'reward'\) holds a NaN or infinite value"),
        (_tamper_stride_zero, r"replay entry action is not dense \(stride \(0, 1\)\)"),
        (_tamper_nan_priority, r"replay priorities \(_sum_tree\) hold a negative, NaN or inf"),
        (_tamper_negative_counter, r"counters.frames=-5 is not a count >= 0"),
    ],
)
def test_a_crafted_or_damaged_replay_is_refused_on_resume(tmp_path, tamper, message):
    """The findings: a NaN reward in the replay ended in 'index -9223372036854775808 is out of
    bounds'; stride-0 rows, NaN priorities and negative counters gave obscure errors."""
    Trainer(tiny_config(tmp_path, total_frames=300), toy_env).run()
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    tamper(state)
    resumed = Trainer(tiny_config(tmp_path, total_frames=300, resume=True), toy_env)
    with pytest.raises(ValueError, match=message) as err:
        resumed.load_state_dict(state)
    assert "\n" not in str(err.value) and "checkpoint.pt" in str(err.value)
