"""scale=real (the paper's real-robot preset) and the driver example recipe end to end."""

import importlib.util
import json
from pathlib import Path

import pytest
from hydra import compose, initialize

from gentlerl.apps.train import config_from_hydra, register_configs
from gentlerl.config.fields import get
from gentlerl.training import make_config
from gentlerl.training.config import iter_fields
from gentlerl.transforms import TouchSensorMap

RECIPES = Path(__file__).resolve().parents[2] / "recipes"


def test_real_scale_is_the_paper_scale_with_the_real_robot_numbers():
    real, paper = make_config("real"), make_config("paper")
    # Huang et al. 2019, "Real robot experiments": 25,000 steps, lr 0.001, intrinsic delay 8,000.
    assert real.collector.total_frames == 25_000 and real.gentleness.reward_delay == 8_000
    assert real.learner.lr_actor == real.learner.lr_critic == 1e-3
    assert (paper.learner.lr_actor, paper.gentleness.reward_delay) == (1e-4, 20_000)
    different = {
        name for name, _ in iter_fields() if get(real, name) != get(paper, name) and name != "scale"
    }
    assert different == {
        "collector.total_frames",
        "collector.init_random_frames",
        "learner.lr_actor",
        "learner.lr_critic",
        "gentleness.reward_delay",
        "logging.eval_every_frames",
        "logging.checkpoint_every_frames",
    }


def test_hydra_scale_real_composes_to_the_preset():
    register_configs()
    with initialize(version_base="1.3", config_path=None):
        cfg = config_from_hydra(compose("gentlerl_train", overrides=["scale=real", "seed=3"]))
    assert cfg == make_config("real", seed=3, run_dir="runs/touch/r+rf+rsp/seed3")


@pytest.mark.slow
def test_driver_example_end_to_end(tmp_path):
    spec = importlib.util.spec_from_file_location("driver_touch", RECIPES / "driver_touch.py")
    recipe = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(recipe)
    results = recipe.main(["--run-dir", str(tmp_path), "--total-frames", "800", "--env", "both"])
    # the file holds what the recipe returned (NaN where a run has no such episode: dumped on
    # both sides, as NaN does not equal itself)
    saved = json.loads((tmp_path / "results.json").read_text())
    assert json.dumps(saved, sort_keys=True) == json.dumps(results, sort_keys=True)
    assert results["sensor_map"]["held_out"]["rmse_pressed_N"] < 0.3
    sensor_map = TouchSensorMap.load(tmp_path / "touch_sensor_map.pt")
    assert bool(sensor_map.fitted) and sensor_map.shape == (5, 1)
    for env in ("driver", "sim"):
        assert 0.0 <= results[env]["eval_final"]["success_rate"] <= 1.0
        # 800 frames: at 400 the simulated env finished no training episode (2026-12-08, the
        # driver's 3); at 800 it finished 4 (the driver's 8)
        assert results[env]["train_episodes"] >= 2
    total = results["driver"]["watchdog_total"]
    # Every step of the collector's and the evaluation env's episodes is checked.
    assert total["checks"] >= 800
    assert max(total["fingertip_trips"], total["block_trips"]) <= total["trips"]
