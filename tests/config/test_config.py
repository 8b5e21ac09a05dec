"""TrainConfig groups, scales, up-front validation, and the hydra app's composition and help."""

import pytest
from hydra import compose, initialize

from gentlerl.agent.builder import AgentBuilder
from gentlerl.apps.train import config_from_hydra, describe, register_configs
from gentlerl.config import SCALES
from gentlerl.envs import TASKS
from gentlerl.envs.batched import available_cores
from gentlerl.rewards import VARIANTS, IntrinsicRewards
from gentlerl.rewards.variants import discounted_horizon
from gentlerl.training import make_config
from gentlerl.training.builders import (
    collection_env_factory,
    default_env_factory,
)
from gentlerl.training.config import iter_fields
from gentlerl.training.migration import group_flat_config
from gentlerl.transforms import DynamicsSurprise
from tests.toy_env import ToyHandEnv


def test_default_is_touch_full_method_cpu_scale():
    cfg = make_config()
    assert (cfg.task, cfg.variant, cfg.scale, cfg.seed) == ("touch", "r+rf+rsp", "cpu", 0)
    assert cfg.gentleness.lam_prime == (2.0, 2.0) and not cfg.learner.episodic_intrinsic
    assert cfg.reward_keys == ["reward", "penalty", "penalty_surprise"]
    assert cfg.collector.kind == "single" and cfg.collector.sigma == 0.3
    assert cfg.replay.n_steps == 5


def test_paper_scale_has_the_papers_numbers():
    cfg = make_config("paper")
    # Huang et al. 2019, Experiments: batch 256, buffer 1M, lr 1e-4, 500k steps, reward delay
    # 20k, dynamics / penalty target periods 5k / 1k, actor 300-200, critic 400-300.
    assert cfg.replay.batch_size == 256 and cfg.replay.buffer_size == 1_000_000
    assert cfg.learner.lr_actor == cfg.learner.lr_critic == 1e-4
    assert cfg.collector.total_frames == 500_000 and cfg.gentleness.reward_delay == 20_000
    assert cfg.learner.episodic_intrinsic  # the paper's D4PG: every head cut at termination
    g = cfg.gentleness
    assert (g.dynamics_target_period, g.penalty_target_period) == (5000, 1000)
    assert cfg.network.actor_hidden == (300, 200) and cfg.network.critic_hidden == (400, 300)
    net = cfg.network
    assert (net.num_atoms, net.v_min, net.v_max, net.bounded_support) == (101, -100, 100, False)


def test_overrides_apply_on_top_of_the_scale():
    cfg = make_config("paper", replay={"batch_size": 64}, gentleness={"lam_prime": [2.0, 1.5]})
    assert cfg.replay.batch_size == 64 and cfg.replay.buffer_size == 1_000_000
    assert cfg.gentleness.lam_prime == (2.0, 1.5) and cfg.gentleness.reward_delay == 20_000


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"variant": "r+foo"}, "variant='r+foo' is not one of"),
        ({"task": "juggle"}, "task='juggle' is not one of"),
        ({"replay": {"batch_size": -1}}, "replay.batch_size=-1 must be in [1, 65536]"),
        ({"replay": {"buffer_size": 0}}, "replay.buffer_size=0 must be in [1, 10000000]"),
        ({"collector": {"init_random_frames": -5}}, "init_random_frames=-5 must be in [0, 10000000000]"),
        ({"gentleness": {"lam": (0.0, 2.0)}}, "lam=(0.0, 2.0) must be [lambda_1 > 0, lambda_2 >= 0]"),
        ({"gentleness": {"lam_prime": (2.0, -1.0)}}, "lam_prime=(2.0, -1.0) must be"),
        ({"gentleness": {"lam": (2.0, 2.0, 1.0)}}, "gentleness.lam=[2.0, 2.0, 1.0] must have 2 values"),
        ({"gentleness": {"lam": (float("nan"), 2.0)}}, "gentleness.lam[0]=nan must be a finite number"),
        ({"learner": {"utd_ratio": float("inf")}}, "learner.utd_ratio=inf must be a finite number"),
        ({"network": {"v_max": float("-inf")}}, "network.v_max=-inf must be a finite number"),
        ({"replay": {"buffer_size": 16, "batch_size": 32}}, "replay.buffer_size=16 must be >= replay.batch_size=32"),
        ({"seed": -1}, "seed=-1 must be in [0, 2147483647]"),
        ({"seed": 2**32}, "seed=4294967296 must be in [0, 2147483647]"),
        ({"seed": 2**32 - 1}, "seed=4294967295 must be in [0, 2147483647]"),
        ({"seed": 2**31}, "seed=2147483648 must be in [0, 2147483647]"),
        ({"seed": True}, "seed=True must be an integer"),
        ({"seed": 1.0}, "seed=1.0 must be an integer"),
        ({"seed": 2**31 - 1, "collector": {"total_frames": 3 * 10**9}}, "seed=2147483647 + collector.total_frames=3000000000 must be < 2**32"),
        ({"run_dir": ""}, "run_dir='' must name a directory"),
        ({"resume": "false"}, "resume='false' must be true, false or 'auto'"),
        ({"replay": {"batch_size": 32.5}}, "replay.batch_size=32.5 must be an integer"),
        ({"collector": {"total_frames": True}}, "collector.total_frames=True must be an integer"),
        ({"logging": {"progress": "yes"}}, "logging.progress='yes' must be true or false"),
        ({"network": {"actor_hidden": (64, 0.5)}}, "network.actor_hidden[1]=0.5 must be an integer"),
        ({"gentleness": {"surprise_nll_floor": float("nan")}}, "gentleness.surprise_nll_floor=nan must be a finite number"),
        ({"env": {"kwargs": {"foo": 1}}}, "env.kwargs ['foo'] are not keywords of task 'touch'; valid: ['action_scale'"),
        ({"env": {"kwargs": {"calibration": "easy"}}}, "env.kwargs.calibration is now env.kwargs.regime (the hand's physics regime)"),
        ({"learner": {"gamma": 1.5}}, "learner.gamma=1.5 must be in (0, 1]"),
        ({"network": {"v_min": 10.0, "v_max": -10.0}}, "network.v_min=10.0 must be < network.v_max=-10.0"),
        ({"network": {"v_min": 1.0}}, "network.v_min=1.0 must be < 0 with bounded_support"),
        ({"learner": {"policy_noise": -0.1}}, "learner.policy_noise=-0.1 must be >= 0"),
        ({"collector": {"kind": "async"}}, "collector.kind='async' is not one of"),
        ({"logging": {"wandb_mode": "cloud"}}, "logging.wandb_mode='cloud' is not one of"),
        ({"learner": {"lr_actor": 0.0}}, "learner.lr_actor=0.0 must be > 0"),
        ({"network": {"actor_hidden": ()}}, "network.actor_hidden=[] must list 1 to 8 layer sizes"),
        ({"bach_size": 3}, "unknown config field(s) ['bach_size']"),
        ({"replay": {"bach_size": 3}}, "unknown config field replay.'bach_size'"),
        ({"replay": 3}, "config group 'replay' takes a mapping, got 3"),
        ({"collector": {"num_envs": 0}}, "collector.num_envs=0 must be in [1, 256] (or null)"),
        ({"collector": {"num_envs": 3}}, "collector.frames_per_batch=200 must be a multiple of collector.num_envs=3"),
        ({"collector": {"num_envs": 4, "kind": "multi"}}, "collector.num_envs=4 with collector.kind=multi"),
        ({"collector": {"env_threads": 0}}, "collector.env_threads=0 must be in [1, 256]"),
        ({"collector": {"kind": "multi", "overlap": True}}, "collector.overlap=true needs collector.kind='single'"),
        ({"learner": {"device": "tpu"}}, "learner.device='tpu' must be cpu, cuda or cuda:N"),
        ({"learner": {"cudagraphs": True}}, "learner.cudagraphs=true needs learner.device=cuda, got 'cpu'"),
    ],
)  # fmt: skip
def test_bad_values_raise_one_clear_error(overrides, message):
    with pytest.raises(ValueError) as err:
        make_config(**overrides)
    assert message in str(err.value)


def test_a_cuda_learner_where_torch_sees_no_gpu_is_refused_up_front(monkeypatch):
    monkeypatch.setattr("torch.cuda.is_available", lambda: False)
    with pytest.raises(
        ValueError, match=r"learner.device='cuda:1': torch sees 0 CUDA device\(s\) here"
    ):
        make_config(learner={"device": "cuda:1"})


def test_every_problem_is_listed_at_once():
    with pytest.raises(ValueError) as err:
        make_config(task="juggle", replay={"batch_size": 0, "alpha": 2.0})
    text = str(err.value)
    assert "task='juggle'" in text and "batch_size=0" in text and "alpha=2.0" in text


def test_a_saved_config_with_the_earlier_regime_keyword_loads_under_the_new_one():
    """``env.kwargs.calibration`` (the hand's physics regime before its rename) of a saved run is
    read as ``env.kwargs.regime``; an external env's keyword of that name is its own, kept."""
    saved = make_config(env={"kwargs": {"regime": "easy", "time_limit": 50}}).to_dict()
    saved["env"]["kwargs"] = {"calibration": "easy", "time_limit": 50}
    cfg = make_config(**group_flat_config(saved))
    assert cfg.env.kwargs == {"regime": "easy", "time_limit": 50}
    assert saved["env"]["kwargs"] == {"calibration": "easy", "time_limit": 50}  # not mutated
    saved["env"]["name"] = "dm_control:finger-spin"
    assert group_flat_config(saved)["env"]["kwargs"] == {"calibration": "easy", "time_limit": 50}


def test_unknown_scale():
    with pytest.raises(ValueError, match="unknown scale 'gpu'; expected one of"):
        make_config("gpu")


def test_task_and_variant_choices_come_from_their_registries():
    choices = {name: f.metadata["choices"] for name, f in iter_fields()}
    assert choices["task"]() == list(TASKS) and choices["variant"]() == list(VARIANTS)
    assert choices["scale"]() == list(SCALES)


def test_help_has_one_line_per_field_with_default_and_choices():
    lines = describe().splitlines()
    assert len(lines) == len(list(iter_fields()))
    (line,) = [x for x in lines if x.strip().startswith("collector.kind=")]
    assert line.split()[0] == "collector.kind=single" and line.endswith("{single, multi, ray}")
    (line,) = [x for x in lines if x.strip().startswith("gentleness.lam_prime=")]
    assert line.split()[0] == "gentleness.lam_prime=[2.0,2.0]"


def _compose(overrides):
    register_configs()
    with initialize(version_base="1.3", config_path=None):
        cfg = compose("gentlerl_train", overrides=overrides)
    return config_from_hydra(cfg)


def test_num_envs_needs_a_batching_env_factory():
    collector = make_config().collector
    assert collector.num_envs is None  # the default: automatic
    # Automatic (null): 4 hands for gentlerl's hand env, 1 for a factory that cannot batch.
    assert collection_env_factory(collector, ToyHandEnv) is ToyHandEnv
    hand = default_env_factory(make_config())
    assert collection_env_factory(collector, hand).keywords["num_envs"] == 4
    odd = make_config(collector={"frames_per_batch": 201, "num_envs": None}).collector
    assert collection_env_factory(odd, hand) is hand
    many = make_config(collector={"env_threads": 64, "num_envs": None}).collector
    with pytest.warns(UserWarning, match="collector.env_threads=64 is more than the"):
        assert collection_env_factory(many, hand).keywords["num_threads"] == available_cores()
    with pytest.raises(ValueError, match="num_envs=4 needs an env factory that takes num_envs"):
        collection_env_factory(make_config(collector={"num_envs": 4}).collector, ToyHandEnv)


def test_app_default_composes_to_the_cpu_default():
    assert _compose([]) == make_config(run_dir="runs/touch/r+rf+rsp/seed0")


def test_app_overrides_groups_scales_and_variant_names_with_plus():
    overrides = ["variant=rf+rsp", "scale=paper", "gentleness.lam_prime=[2,3]", "seed=4",
                 "task=fragile", "replay.batch_size=64"]  # fmt: skip
    cfg = _compose(overrides)
    assert cfg.variant == "rf+rsp" and cfg.gentleness.lam_prime == (2.0, 3.0)
    assert cfg.replay.batch_size == 64 and cfg.replay.buffer_size == 1_000_000
    assert cfg.run_dir == "runs/fragile/rf+rsp/seed4"
    assert cfg == make_config(
        "paper",
        variant="rf+rsp",
        seed=4,
        task="fragile",
        run_dir="runs/fragile/rf+rsp/seed4",
        gentleness={"lam_prime": (2, 3)},
        replay={"batch_size": 64},
    )


@pytest.mark.parametrize(
    ("scale", "episodic"), [("cpu", [True, True, False]), ("paper", [True] * 3)]
)
def test_learner_cuts_the_bootstrap_of_intrinsic_heads_only_at_paper_scale(scale, episodic):
    learner = AgentBuilder(make_config(scale), ToyHandEnv()).make_learner()
    assert learner.loss.reward_keys == ["reward", "penalty", "penalty_surprise"]
    assert learner.loss.episodic.tolist() == episodic


def test_critic_supports_per_head_at_cpu_scale_shared_at_paper_scale():
    env = ToyHandEnv()
    cpu = AgentBuilder(make_config("cpu"), env).make_learner().loss.value_network.module
    span = discounted_horizon(0.99, env.time_limit)  # dense heads: 1 per step x the horizon
    # reward, penalty, penalty_surprise: the task pays once (+-10), the dense heads +-span, the
    # never-positive penalty tops at 0
    assert cpu.v_min == pytest.approx((-10.0, -span, -span))
    assert cpu.v_max == pytest.approx((10.0, 0.0, span))
    paper = AgentBuilder(make_config("paper"), env).make_learner().loss.value_network.module
    assert paper.v_min == (-100.0,) * 3 and paper.v_max == (100.0,) * 3  # the paper's (-100, 100)


@pytest.mark.parametrize(("scale", "factor"), [("cpu", 0.002), ("paper", 1.0), ("real", 1.0)])
def test_dynamics_surprise_is_scaled_down_at_cpu_scale_only(scale, factor):
    cfg = make_config(scale, variant="r+rf+rs", gentleness={"surprise_scale": 2.0})
    rewards = IntrinsicRewards(
        cfg.variant, cfg.gentleness, obs_dim=63, action_dim=20, feature_shapes={"joint_pos": (24,)}
    )
    (surprise,) = [t for t in rewards.transform if isinstance(t, DynamicsSurprise)]
    assert cfg.gentleness.dynamics_surprise_scale == factor
    assert surprise.scale == pytest.approx(2.0 * factor)


def test_a_checkpoint_config_with_the_old_name_of_rescore_surprise_keeps_its_value():
    """``gentleness.recompute_surprise`` (the field's name before "rescore" became the one verb)
    loads as ``rescore_surprise`` with the value it was saved with, not today's default."""
    from gentlerl.training.config import make_config
    from gentlerl.training.migration import group_flat_config

    saved = make_config().to_dict()
    del saved["gentleness"]["rescore_surprise"]
    saved["gentleness"]["recompute_surprise"] = False
    grouped = group_flat_config(saved)
    assert "recompute_surprise" not in grouped["gentleness"]
    assert grouped["gentleness"]["rescore_surprise"] is False


def test_help_marks_the_ablation_knobs_the_reproduction_grid_switches():
    """Every key an ablation of recipes/grids/reproduce.sh sets is marked ``[ablation]`` in
    ``--help`` (the support's bounds excepted: they are the regime's, not an ablation's), and
    nothing else is."""
    import re
    from pathlib import Path

    script = (Path(__file__).resolve().parents[2] / "recipes/grids/reproduce.sh").read_text()
    ablations = script[script.index('case "$method" in') :]
    switched = set(re.findall(r"--set ((?:gentleness|network|learner)\.\w+)=", ablations))
    switched -= {"network.v_min", "network.v_max"}
    marked = {
        line.split("=")[0].strip() for line in describe().splitlines() if "[ablation]" in line
    }
    assert switched and switched <= marked
    assert marked == {name for name, f in iter_fields() if f.metadata.get("ablation")}


def test_the_largest_seed_and_every_seed_a_run_derives_from_it_are_taken_by_every_generator():
    """A run seeds numpy (< 2**32), torch and its envs with its seed, evaluation with seed +
    EVAL_SEED_OFFSET, worker i with seed + i and a resumed collector with seed + its frames: at
    the largest seed and frames the config accepts, each of those is a valid seed."""
    import numpy as np
    import torch

    from gentlerl.config.groups import CollectorConfig
    from gentlerl.config.limits import MAX_SEED
    from gentlerl.training.evaluation import EVAL_SEED_OFFSET

    frames = 2**32 - 1 - MAX_SEED
    cfg = make_config(seed=MAX_SEED, collector={"total_frames": frames})
    workers = CollectorConfig.__dataclass_fields__["num_workers"].metadata["bounds"].high
    derived = [cfg.seed + EVAL_SEED_OFFSET, cfg.seed + int(workers) - 1, cfg.seed + frames - 1]
    for seed in [cfg.seed, *derived]:
        np.random.RandomState(seed)
        torch.manual_seed(seed)
