"""TrainConfig scales, up-front validation, and the hydra recipe's composition."""

from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf
from torchrl.envs import RenameTransform, TransformedEnv

from gentlerl.training import SCALES, TrainConfig, make_config
from gentlerl.training.builders import check_env_keys, collection_env_factory, make_learner
from gentlerl.transforms import VARIANTS, make_reward_transforms
from tests.toy_env import ToyHandEnv

CONFIG_DIR = Path(__file__).resolve().parents[1] / "recipes" / "config"


def test_default_is_touch_full_method_cpu_scale():
    cfg = make_config()
    assert (cfg.task, cfg.variant, cfg.scale, cfg.seed) == ("touch", "r+rf+rsp", "cpu", 0)
    assert cfg.lam_prime == (2.0, 2.0) and not cfg.episodic_intrinsic
    assert cfg.reward_keys == ["reward", "penalty", "penalty_surprise"]
    assert cfg.collector == "single" and cfg.sigma == 0.3 and cfg.n_steps == 5


def test_paper_scale_has_the_papers_numbers():
    cfg = make_config("paper")
    # Huang et al. 2019, Experiments: batch 256, buffer 1M, lr 1e-4, 500k steps, reward delay
    # 20k, dynamics / penalty target periods 5k / 1k, actor 300-200, critic 400-300.
    assert cfg.batch_size == 256 and cfg.buffer_size == 1_000_000
    assert cfg.lr_actor == cfg.lr_critic == 1e-4
    assert cfg.total_frames == 500_000 and cfg.reward_delay == 20_000
    assert cfg.episodic_intrinsic  # the paper's D4PG: every head cut at termination
    assert (cfg.dynamics_target_period, cfg.penalty_target_period) == (5000, 1000)
    assert cfg.actor_hidden == (300, 200) and cfg.critic_hidden == (400, 300)
    assert (cfg.num_atoms, cfg.v_min, cfg.v_max) == (101, -100.0, 100.0)


def test_overrides_apply_on_top_of_the_scale():
    cfg = make_config("paper", batch_size=64, lam_prime=[2.0, 1.5])
    assert cfg.batch_size == 64 and cfg.lam_prime == (2.0, 1.5) and cfg.buffer_size == 1_000_000


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"variant": "r+foo"}, "variant='r+foo' is not one of"),
        ({"task": "juggle"}, "task='juggle' is not one of"),
        ({"batch_size": -1}, "batch_size=-1 must be >= 1"),
        ({"buffer_size": 0}, "buffer_size=0 must be >= 1"),
        ({"init_random_frames": -5}, "init_random_frames=-5 must be >= 0"),
        ({"lam": (0.0, 2.0)}, "lam=(0.0, 2.0) must be [lambda_1 > 0, lambda_2 >= 0]"),
        ({"lam_prime": (2.0, -1.0)}, "lam_prime=(2.0, -1.0) must be"),
        ({"lam": (2.0, 2.0, 1.0)}, "lam=(2.0, 2.0, 1.0) must be"),
        ({"gamma": 1.5}, "gamma=1.5 must be in (0, 1]"),
        ({"v_min": 10.0, "v_max": -10.0}, "v_min=10.0 must be < v_max=-10.0"),
        ({"penalty_v_max": -20.0}, "penalty_v_max=-20.0 must be > v_min=-10.0"),
        ({"policy_noise": -0.1}, "policy_noise=-0.1 must be >= 0"),
        ({"collector": "async"}, "collector='async' is not one of"),
        ({"wandb_mode": "cloud"}, "wandb_mode='cloud' is not one of"),
        ({"lr_actor": 0.0}, "lr_actor=0.0 must be > 0"),
        ({"actor_hidden": ()}, "actor_hidden=() must be a non-empty list"),
        ({"bach_size": 3}, "unknown config field(s) ['bach_size']"),
        ({"num_envs": 0}, "num_envs=0 must be >= 1"),
        ({"num_envs": 3}, "frames_per_batch=200 must be a multiple of num_envs=3"),
        ({"env_threads": 0}, "env_threads=0 must be >= 1"),
    ],
)
def test_bad_values_raise_one_clear_error(overrides, message):
    with pytest.raises(ValueError) as err:
        make_config(**overrides)
    assert message in str(err.value)


def test_every_problem_is_listed_at_once():
    with pytest.raises(ValueError) as err:
        make_config(task="juggle", batch_size=0, alpha=2.0)
    text = str(err.value)
    assert "task='juggle'" in text and "batch_size=0" in text and "alpha=2.0" in text


def test_unknown_scale():
    with pytest.raises(ValueError, match="unknown scale 'gpu'; expected one of"):
        make_config("gpu")


def test_missing_env_keys_are_reported_before_training():
    stack = make_reward_transforms("r+rf", reward_delay=0)
    check_env_keys(ToyHandEnv(), stack)  # the toy env has the hand env's keys
    no_touch = TransformedEnv(ToyHandEnv(), RenameTransform(["touch"], ["force"]))
    with pytest.raises(ValueError, match="the env does not produce 'touch'"):
        check_env_keys(no_touch, stack)
    no_success = TransformedEnv(ToyHandEnv(), RenameTransform(["success"], ["win"]))
    with pytest.raises(ValueError, match=r"key\(s\) \['success'\] needed by the run"):
        check_env_keys(no_success, stack)


def _compose(overrides):
    ConfigStore.instance().store(name="train_config", node=TrainConfig)
    with initialize_config_dir(str(CONFIG_DIR), version_base="1.3"):
        cfg = compose("config", overrides=overrides)
    return make_config(**OmegaConf.to_container(cfg, resolve=True))


def test_num_envs_needs_a_batching_env_factory():
    assert collection_env_factory(make_config(), ToyHandEnv) is ToyHandEnv
    with pytest.raises(ValueError, match="num_envs=4 needs an env factory that takes num_envs"):
        collection_env_factory(make_config(num_envs=4), ToyHandEnv)


def test_recipe_default_composes_to_the_cpu_default():
    assert _compose([]) == make_config(run_dir="runs/touch/r+rf+rsp/seed0")


def test_recipe_overrides_with_plus_in_variant_names():
    cfg = _compose(["variant=rf+rsp", "scale=paper", "lam_prime=[2,3]", "seed=4", "task=fragile"])
    assert cfg.variant == "rf+rsp" and cfg.lam_prime == (2.0, 3.0) and cfg.batch_size == 256
    assert cfg.run_dir == "runs/fragile/rf+rsp/seed4"


def test_recipe_has_one_config_per_variant_naming_it():
    files = {p.stem: yaml.safe_load(p.read_text()) for p in (CONFIG_DIR / "variant").glob("*.yaml")}
    assert sorted(files) == sorted(VARIANTS)
    assert all(content["variant"] == name for name, content in files.items())


def test_recipe_scale_files_match_the_library_presets():
    for scale, preset in SCALES.items():
        content = yaml.safe_load((CONFIG_DIR / "scale" / f"{scale}.yaml").read_text())
        assert content.pop("scale") == scale
        as_config = make_config(scale, **content)
        assert as_config == make_config(scale), scale
        assert sorted(content) == sorted(preset), scale


@pytest.mark.parametrize(
    ("scale", "episodic"), [("cpu", [True, True, False]), ("paper", [True] * 3)]
)
def test_learner_cuts_the_bootstrap_of_intrinsic_heads_only_at_paper_scale(scale, episodic):
    learner = make_learner(make_config(scale), obs_dim=63, action_dim=20)
    assert learner.loss.reward_keys == ["reward", "penalty", "penalty_surprise"]
    assert learner.loss.episodic.tolist() == episodic


@pytest.mark.parametrize(
    ("scale", "v_max"), [("cpu", [10.0, 0.0, 10.0]), ("paper", [100.0, 100.0, 100.0])]
)
def test_penalty_critic_support_tops_at_zero_at_cpu_scale(scale, v_max):
    learner = make_learner(make_config(scale), obs_dim=63, action_dim=20)
    assert learner.loss.v_max.tolist() == v_max  # reward, penalty, penalty_surprise
    assert learner.loss.v_min.tolist() == [make_config(scale).v_min] * 3
