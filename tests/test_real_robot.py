"""scale=real (the paper's real-robot preset) and the driver example recipe end to end."""

import importlib.util
import json
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from gentlerl.training import TrainConfig, make_config
from gentlerl.transforms import TouchCalibration

RECIPES = Path(__file__).resolve().parents[1] / "recipes"


def test_real_scale_is_the_paper_scale_with_the_real_robot_numbers():
    real, paper = make_config("real"), make_config("paper")
    # Huang et al. 2019, "Real robot experiments": 25,000 steps, lr 0.001, intrinsic delay 8,000.
    assert (real.total_frames, real.lr_actor, real.lr_critic, real.reward_delay) == (
        25_000,
        1e-3,
        1e-3,
        8_000,
    )
    assert (paper.lr_actor, paper.reward_delay) == (1e-4, 20_000)
    different = {k for k, v in real.to_dict().items() if v != paper.to_dict()[k] and k != "scale"}
    assert different == {
        "total_frames",
        "init_random_frames",
        "lr_actor",
        "lr_critic",
        "reward_delay",
        "eval_every_frames",
        "checkpoint_every_frames",
    }


def test_hydra_scale_real_composes_to_the_preset():
    ConfigStore.instance().store(name="train_config", node=TrainConfig)
    with initialize_config_dir(str(RECIPES / "config"), version_base="1.3"):
        cfg = compose("config", overrides=["scale=real", "seed=3"])
    values = OmegaConf.to_container(cfg, resolve=True)
    assert make_config(**values) == make_config("real", seed=3, run_dir=values["run_dir"])


@pytest.mark.slow
def test_driver_example_end_to_end(tmp_path):
    spec = importlib.util.spec_from_file_location("driver_touch", RECIPES / "driver_touch.py")
    recipe = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(recipe)
    results = recipe.main(["--run-dir", str(tmp_path), "--total-frames", "400", "--env", "both"])
    assert json.loads((tmp_path / "results.json").read_text()) == results
    assert results["calibration"]["held_out"]["rmse_pressed_N"] < 0.3
    calibration = TouchCalibration.load(tmp_path / "touch_calibration.pt")
    assert bool(calibration.fitted) and calibration.shape == (5, 1)
    for env in ("driver", "sim"):
        assert 0.0 <= results[env]["eval_final"]["success_rate"] <= 1.0
        assert results[env]["train_episodes"] >= 2  # 400 frames of <= 200-step episodes
    total = results["driver"]["watchdog_total"]
    # Every step of the collector's and the evaluation env's episodes is checked.
    assert total["checks"] >= 400
    assert max(total["fingertip_trips"], total["block_trips"]) <= total["trips"]
