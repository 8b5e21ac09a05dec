"""What the trainer builds before its loop: the agent from one probed env, the collector for the
rest of a run, the config file it writes, and the progress it reports."""

import pytest
import yaml
from torchrl.envs import RenameTransform, TransformedEnv

from gentlerl.agent.builder import configured_learner
from gentlerl.config.layout import RunLayout
from gentlerl.training.builders import make_agent, make_run_collector, write_config
from gentlerl.training.logging import Progress
from tests.helpers import tiny_config, toy_env
from tests.toy_env import ToyHandEnv


def test_make_agent_is_sized_by_one_probe_env_which_it_closes(tmp_path):
    probes = []

    def factory():
        probes.append(toy_env())
        return probes[-1]

    cfg = tiny_config(tmp_path, total_frames=500, init_random_frames=200, utd_ratio=0.5)
    agent = make_agent(cfg, factory)
    assert len(probes) == 1 and probes[0].is_closed
    builder = agent.builder
    assert (builder.obs_dim, builder.action_dim, builder.horizon) == (63, 20, 50)
    assert (
        agent.rewards.reward_keys
        == builder.reward_keys
        == ["reward", "penalty", "penalty_surprise"]
    )
    assert agent.writer.rb is agent.rb and len(agent.rb) == 0
    assert agent.beta_schedule.num_steps == 0.5 * (500 - 200)  # one step per update
    assert not any(tmp_path.iterdir())  # building writes nothing


def test_make_agent_refuses_an_env_without_the_keys_the_run_reads(tmp_path):
    def no_touch():
        return TransformedEnv(ToyHandEnv(), RenameTransform(["touch"], ["force"]))

    with pytest.raises(ValueError, match="reads 'touch', which the env's spec lacks"):
        make_agent(tiny_config(tmp_path), no_touch)


def test_the_run_collector_collects_what_the_run_has_left(tmp_path):
    cfg = tiny_config(tmp_path, total_frames=500, init_random_frames=200, frames_per_batch=100)
    agent = make_agent(cfg, toy_env)
    policy = agent.builder.make_policy(configured_learner(agent.loss, cfg.learner))
    collector = make_run_collector(cfg, toy_env, policy, frames=300)
    try:
        assert collector.init_random_frames == 0
        assert sum(batch.numel() for batch in collector) == 500 - 300
    finally:
        collector.shutdown()


def test_write_config_is_the_run_directory_config(tmp_path):
    cfg, layout = tiny_config(tmp_path), RunLayout(tmp_path)
    config = write_config(cfg, layout)
    assert layout.is_run() and not layout.has_started()
    assert yaml.safe_load(layout.config.read_text()) == config
    assert config["collector"]["total_frames"] == cfg.collector.total_frames


def test_progress_counts_from_where_the_loop_started():
    progress = Progress(["reward"], total=1000, frames=400, enabled=True)
    assert progress.env_steps_per_s(400) == 0.0 and progress.env_steps_per_s(500) > 0
    progress.advance(100, [{"frames": 500, "success_rate": 0.5}])
    assert progress.bar.n == 500
    assert progress.bar.postfix == "success=0.00, max_impact=0.00 N, eval=0.50"
    progress.close()
