"""The shared training loop on the toy hand env: determinism, update-to-data ratio, the run
directory's logging contract, episode statistics, evaluation, and learning."""

import csv
from pathlib import Path

import pytest
import torch
import yaml
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.envs import Compose, TransformedEnv

from gentlerl import keys
from gentlerl.config.layout import RunLayout
from gentlerl.training import Trainer, load_policy, make_config, train
from gentlerl.training.evaluation import evaluate
from gentlerl.training.logging import EVAL_COLUMNS, EpisodeStats, episode_transforms
from gentlerl.transforms import ImpactPenalty
from tests.helpers import read_scalar, tiny_config, toy_env
from tests.toy_env import ToyHandEnv


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("run")
    trainer = Trainer(tiny_config(run_dir), toy_env)
    summary = trainer.run()
    return run_dir, trainer, summary


def test_same_seed_same_losses_other_seed_other_losses(tmp_path):
    for name, seed in (("first", 0), ("again", 0), ("seed1", 1)):
        train(tiny_config(tmp_path / name, collector={"total_frames": 600}, seed=seed), toy_env)
    for name in ("train/loss_value", "train/loss_actor", "train/model_penalty"):
        first = read_scalar(tmp_path / "first", name)
        assert len(first) == 4 and read_scalar(tmp_path / "again", name) == first, name
        assert read_scalar(tmp_path / "seed1", name)[0] != first[0], name


#: Scalars that measure speed, different in every run.
TIMING = ("train/env_steps_per_s", "train/updates_per_s", "train/wall_s")


def _logged_scalars(run_dir: Path) -> dict[str, list[tuple[int, float]]]:
    root = RunLayout(run_dir).scalars
    names = [str(p.relative_to(root).with_suffix("")) for p in root.glob("**/*.csv")]
    return {name: read_scalar(run_dir, name) for name in names if name not in TIMING}


def test_same_seed_same_logged_scalars_with_the_hand_env(tmp_path):
    # The default env factory (the hand env): its first block position is drawn at the first
    # reset, which the collector does before ``set_seed`` (unseeded, 23 of 25 scalars differed).
    # Large actions (action_scale 0.3) touch the block within the 30-step episodes.
    runs = {}
    for name in ("first", "again"):
        cfg = tiny_config(
            tmp_path / name, seed=3, variant="r+rf+rsp", total_frames=300, reward_delay=0,
            kwargs={"time_limit": 30, "action_scale": 0.3}, eval_every_frames=300,
            eval_episodes=1, log_every_updates=25,
        )  # fmt: skip
        train(cfg)
        runs[name] = _logged_scalars(tmp_path / name)
    calibration = [
        name for name in runs["first"] if name.startswith(("calibration/", "surprise_sources/"))
    ]
    # predicted, realised, bias of each critic head; where r^sp comes from (9 numbers)
    assert len(calibration) == 3 * 3 + 9
    # 24 + train/penalty_surprise_per_contact_step (recomputed r^sp at sampling)
    assert len(runs["first"]) - len(calibration) == 25, sorted(runs["first"])
    impacts = [value for _, value in runs["first"]["episode/max_impact"]]
    assert len(impacts) >= 6 and len(set(impacts)) > 1  # real episodes, not a constant
    assert runs["again"] == runs["first"]


@pytest.mark.parametrize("utd_ratio", [0.5, 2.0])
def test_update_to_data_ratio(tmp_path, utd_ratio):
    trainer = Trainer(
        tiny_config(tmp_path, learner={"utd_ratio": utd_ratio}, collector={"total_frames": 500}),
        toy_env,
    )
    trainer.run()
    # Updates start after the 200 random frames: utd * (500 - 200) updates.
    assert trainer.counters == {
        "frames": 500,
        "updates": int(utd_ratio * 300),
        "update_credit": 0.0,
    }


def test_run_directory_follows_the_logging_contract(finished_run):
    run_dir, trainer, summary = finished_run
    layout = RunLayout(run_dir)
    assert layout.is_run() and layout.done.exists() and layout.checkpoint.exists()
    config = yaml.safe_load(layout.config.read_text())
    for key in ("task", "variant", "seed", "scale", "collector", "gentleness"):
        assert key in config
    assert config["gentleness"]["lam_prime"] == [2.0, 2.0]
    assert config["variant"] == "r+rf+rsp" and config["collector"]["total_frames"] == 1000
    names = [
        "episode/return_reward",
        "episode/return_penalty",
        "episode/return_penalty_surprise",
        "episode/success",
        "episode/broken",
        "episode/max_impact",
        "episode/length",
        "eval/success_rate",
        "eval/max_impact_mean",
        "eval/return",
        "train/loss_actor",
        "train/loss_value",
        "train/loss_value_reward",
        "train/loss_value_penalty_surprise",
        "train/batch_penalty",
        "train/intrinsic_on",
        "train/updates_per_s",
        "train/env_steps_per_s",
        "train/wall_s",
        "train/model_penalty",
    ]
    for name in names:
        rows = read_scalar(run_dir, name)
        # x-axis = env frames: collector batches are 100 frames.
        assert rows and all(step % 100 == 0 and 0 < step <= 1000 for step, _ in rows), name
    # Evaluations at 500 and 1000; the one at 1000 is the final one (logged once, not twice).
    assert [s for s, _ in read_scalar(run_dir, "eval/success_rate")] == [500, 1000]
    lengths = [v for _, v in read_scalar(run_dir, "episode/length")]
    assert all(1 <= n <= 50 for n in lengths)
    with layout.eval_episodes.open() as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == EVAL_COLUMNS[:-1] and len(rows) == 1 + 2 * 2  # no tolerance: no cost
    assert summary == {k: v for k, v in trainer.state.eval_history[-1].items() if k != "frames"}


def test_best_policy_is_the_best_evaluation_of_the_run(finished_run):
    run_dir, trainer, _ = finished_run

    def rank(r):
        return (r["success_rate"], -r["broken_rate"], -r["max_impact_mean"])

    best = max(trainer.state.eval_history, key=rank)  # ties: the earliest evaluation stays
    path = RunLayout(run_dir).best_policy
    state = torch.load(path, weights_only=False)
    assert state["eval"] == best == trainer.state.best_eval
    cfg, actor = load_policy(path)
    assert cfg.variant == "r+rf+rsp" and set(actor.state_dict()) == set(state["actor"])


def test_best_policy_ranks_success_then_breaks_then_impact(tmp_path):
    trainer = Trainer(tiny_config(tmp_path), toy_env)
    path = RunLayout(tmp_path).best_policy

    def offer(frames, success, broken, impact):
        result = dict(frames=frames, success_rate=success, broken_rate=broken)
        trainer.keep_best({**result, "max_impact_mean": impact, "return": 0.0})
        return torch.load(path, weights_only=False)["eval"]["frames"]

    assert offer(1, 0.5, 0.0, 1.0) == 1
    assert offer(2, 0.4, 0.0, 0.1) == 1  # less success loses, however gentle
    assert offer(3, 0.5, 0.0, 0.8) == 3  # same success, gentler: kept
    assert offer(4, 0.5, 0.0, 0.8) == 3  # a tie keeps the earlier policy
    assert offer(5, 0.9, 0.1, 3.0) == 5
    assert offer(6, 0.9, 0.0, 4.0) == 6  # same success, fewer breaks


def test_intrinsic_rewards_switch_on_after_the_reward_delay(finished_run):
    run_dir, trainer, _ = finished_run
    # 400 updates in all, logged every 50; the reward delay is 100 model updates.
    on = read_scalar(run_dir, "train/intrinsic_on")
    updates_at = {step: 0.5 * (step - 200) for step, _ in on}
    assert [v for s, v in on] == [float(updates_at[s] >= 100) for s, _ in on]
    assert trainer.rewards.intrinsic_on and trainer.counters["updates"] == 400


def test_episode_stats_span_batches():
    def batch(traj, reward, touch0, done, steps, running_return):
        n = len(traj)
        touch = torch.zeros(n, 5, 3)
        touch[:, 0, 0] = torch.tensor(touch0)
        reward = torch.tensor(reward).reshape(n, 1)
        nxt = {
            keys.REWARD: reward,
            keys.PENALTY: -torch.ones(n, 1),
            keys.IMPACT: touch[:, :, 0],
            keys.SUCCESS: reward > 0,
            keys.BROKEN: torch.zeros(n, 1, dtype=torch.bool),
            keys.DONE: torch.tensor(done).reshape(n, 1),
            # What StepCounter / RewardSum write: the running length and task return.
            "step_count": torch.tensor(steps).reshape(n, 1),
            "episode_reward": torch.tensor(running_return).reshape(n, 1),
        }
        return TensorDict({("collector", "traj_ids"): torch.tensor(traj), "next": nxt}, [n])

    tracker = EpisodeStats([keys.REWARD, keys.PENALTY])
    first = batch([0, 0, 0], [0.0, 0.0, 0.0], [1.0, 4.0, 2.0], [0, 0, 0], [1, 2, 3], [0, 0, 0])
    assert tracker.update(first) == []
    second = batch([0, 1, 1], [1.0, 0.0, 0.0], [3.0, 0.5, 0.0], [1, 0, 1], [4, 1, 2], [1, 0, 0])
    assert tracker.update(second) == [
        # Episode 0: 4 steps, max impact 4 N (second step), success on its last step.
        dict(return_reward=1.0, return_penalty=-4.0, success=1.0, broken=0.0, max_impact=4.0,
             length=4.0),
        dict(return_reward=0.0, return_penalty=-2.0, success=0.0, broken=0.0, max_impact=0.5,
             length=2.0),
    ]  # fmt: skip


def test_episode_stats_of_a_collector_match_its_trajectories():
    # 7-step episodes collected 5 frames at a time: every episode spans two or three batches.
    env = TransformedEnv(ToyHandEnv(time_limit=7), Compose(*episode_transforms(), ImpactPenalty()))
    press = torch.zeros(20)
    press[1:5] = 1.0  # fingertips 1-4 pass the wall at step 6: impacts, no success
    policy = TensorDictModule(
        lambda obs: press.expand(*obs.shape[:-1], 20), ["observation"], ["action"]
    )
    collector = Collector(
        env, policy, frames_per_batch=5, total_frames=35, auto_register_policy_transforms=False
    )
    tracker, batches, episodes = EpisodeStats([keys.REWARD, keys.PENALTY]), [], []
    for data in collector:
        batches.append(data)
        episodes += tracker.update(data)
    collector.shutdown()
    data = torch.cat(batches)
    assert [e["length"] for e in episodes] == [7.0] * 5
    for tid, ep in enumerate(episodes):
        steps = data[data["collector", "traj_ids"] == tid]["next"]
        assert ep["return_reward"] == pytest.approx(steps[keys.REWARD].sum().item())
        assert ep["return_penalty"] == pytest.approx(steps[keys.PENALTY].sum().item())
        assert ep["max_impact"] == pytest.approx(steps[keys.IMPACT].max().item())
        assert ep["return_penalty"] < 0 and ep["max_impact"] > 0


def test_evaluation_is_deterministic_with_hand_computed_numbers():
    # Pressing joint 0 at full speed: position +0.1 per step, force 20 N per unit past 0.5 on
    # channel 0 and a tenth of that on channel 1, so each pressing step's impact is
    # 2 + 0.2 = 2.2 N; the force passes 5 N at position 0.8, the 8th step (reward 1).
    press = torch.zeros(20)
    press[0] = 1.0
    actor = TensorDictModule(
        lambda obs: press.expand(*obs.shape[:-1], 20), ["observation"], ["action"]
    )
    env = TransformedEnv(toy_env(), ImpactPenalty())
    summary, episodes = evaluate(env, actor, episodes=2, max_steps=50)
    assert summary["success_rate"] == 1.0 and summary["broken_rate"] == 0.0
    assert summary["max_impact_mean"] == pytest.approx(2.2, abs=1e-5)
    assert summary["return"] == 1.0 and episodes[0] == episodes[1]


def test_learns_the_toy_press_task(tmp_path):
    cfg = tiny_config(
        tmp_path,
        variant="r",
        collector={"total_frames": 4000},
        logging={"eval_every_frames": 4000},
    )
    summary = train(cfg, toy_env)
    assert summary["success_rate"] == 1.0


def test_multi_process_collector_keeps_rows_time_contiguous(tmp_path):
    collector = dict(kind="multi", num_workers=2, total_frames=400)
    cfg = tiny_config(tmp_path, collector=collector, logging={"eval_episodes": 1})
    trainer = Trainer(cfg, toy_env)
    trainer.run()
    # Batches are [2 workers, 50 steps]; each worker's row keeps its last 5 steps pending.
    assert trainer.counters["frames"] == 400 and trainer.counters["updates"] == 100
    assert len(trainer.rewards.buffer) == 400 and len(trainer.rb) == 400 - 2 * 5
    # n-step windows never mix workers: the toy env's joint position moves by at most 0.1 per
    # step, so n = steps_to_next_obs <= 5 steps can move it by at most 0.5.
    data = trainer.rb[:]
    jump = (data["next", "observation"][:, :20] - data["observation"][:, :20]).abs().amax(-1)
    assert (jump <= 0.1 * data["steps_to_next_obs"].squeeze(-1) + 1e-5).all()


@pytest.mark.slow
def test_default_recipe_learns_touch(tmp_path):
    """The default recipe (touch, r+rf+rsp, cpu scale) on the ``easy`` hand reaches >= 0.8
    evaluation success (10 noise-free episodes) on the 2-core CPU, and still succeeds at the end
    of the run. Measured there on 3 seeds x 100k frames: every seed reaches 1.0 by 15k frames.
    On the default ``paper`` hand it does not yet (one run: evaluation
    success 0 from 15k to 40k frames), so this test pins the hand it was measured on."""
    cfg = make_config(
        run_dir=str(tmp_path),
        logging={"wandb_mode": "disabled", "progress": False},
        collector={"total_frames": 30_000},
        env={"kwargs": {"regime": "easy"}},
    )
    trainer = Trainer(cfg)
    trainer.run()
    learned = [
        e["success_rate"]
        for e in trainer.state.eval_history
        if e["frames"] > cfg.collector.init_random_frames
    ]
    assert max(learned) >= 0.8
    assert learned[-1] >= 0.8


def test_the_ray_cluster_is_joined_after_the_agent_is_built_and_before_anything_is_written(
    tmp_path, monkeypatch
):
    """The set-up's last check: a Ray run whose cluster cannot be joined (here: Ray absent or
    refused) stops with the cluster's error, after the agent was built, and leaves no run
    directory behind."""
    import gentlerl.training.loop as loop
    from gentlerl.distributed.cluster import ClusterError

    built = []
    make_agent = loop.make_agent
    monkeypatch.setattr(loop, "make_agent", lambda *a: built.append(1) or make_agent(*a))

    def refuse(address):
        assert built, "the cluster is joined once the agent is built"
        raise ClusterError(f"no Ray cluster found for address={address!r}")

    monkeypatch.setattr(loop, "join_cluster", refuse)
    run_dir = tmp_path / "ray_run"
    cfg = tiny_config(run_dir, collector={"kind": "ray", "num_workers": 2, "ray_address": "auto"})
    with pytest.raises(ClusterError, match="address='auto'"):
        Trainer(cfg, toy_env)
    assert built and not run_dir.exists()


def test_the_deprecated_trainer_update_warns_and_takes_one_update(tmp_path):
    trainer = Trainer(tiny_config(tmp_path, total_frames=300), toy_env)
    trainer.run()
    before = trainer.counters["updates"]
    with pytest.warns(DeprecationWarning, match=r"Trainer.update\(\) is deprecated"):
        metrics = trainer.update()
    assert trainer.counters["updates"] == before + 1
    assert {"loss_value", "loss_actor", "model_penalty"} <= set(metrics)
