"""Each setting is declared once (gentlerl.config): its range and resumable flag drive validation
and resume, and the config package imports nothing else of gentlerl."""

import dataclasses
import subprocess
import sys

import pytest

from gentlerl.config import CollectorConfig, Range, declared_problems, iter_fields, setting
from gentlerl.distributed.collector import make_ray_collector, ray_problems
from gentlerl.training.config import TrainConfig, make_config
from gentlerl.training.resume import SAFE_TO_CHANGE

#: What a resume could change before the flag moved onto each declaration, written out once.
OLD_SAFE_TO_CHANGE = (
    "run_dir resume scale num_threads "
    "collector.total_frames collector.frames_per_batch collector.init_random_frames "
    "collector.sigma collector.overlap collector.env_threads collector.ray_address "
    "collector.cpus_per_worker collector.memory_per_worker_gb collector.weight_sync_every "
    "replay.batch_size replay.alpha replay.beta "
    "learner.utd_ratio learner.lr_actor learner.lr_critic learner.target_update_period "
    "learner.policy_noise "
    "gentleness.reward_delay gentleness.dynamics_target_period "
    "gentleness.penalty_target_period gentleness.model_batch_size gentleness.lr_model "
    "logging.eval_every_frames logging.eval_episodes logging.log_every_updates "
    "logging.checkpoint_every_frames logging.wandb_mode logging.wandb_project "
    "logging.progress"
).split()


#: Fields declared resumable since: a checkpoint's tensors load onto any learner device.
NEW_SAFE_TO_CHANGE = ("learner.device",)


def test_safe_to_change_is_the_fields_declared_resumable():
    assert len(OLD_SAFE_TO_CHANGE) == 34
    assert frozenset([*OLD_SAFE_TO_CHANGE, *NEW_SAFE_TO_CHANGE]) == SAFE_TO_CHANGE


def test_the_config_package_imports_nothing_else_of_gentlerl():
    code = (  # beyond what ``import gentlerl`` itself loads (its start-up: gentlerl.opengl)
        "import gentlerl, sys; loaded = set(sys.modules); "
        "import gentlerl.config, gentlerl.config.groups, gentlerl.config.rules; "
        "print(sorted(m for m in set(sys.modules) - loaded if m.startswith('gentlerl.') "
        "and not m.startswith('gentlerl.config')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("collector.frames_per_batch", -3, "collector.frames_per_batch=-3 must be in [1, 100000]"),
        ("collector.sigma", -0.5, "collector.sigma=-0.5 must be >= 0"),
        (
            "collector.memory_per_worker_gb",
            0.0,
            "collector.memory_per_worker_gb=0.0 must be in (0, 1024]",
        ),
        ("gentleness.lr_model", -1e-3, "gentleness.lr_model=-0.001 must be > 0"),
        ("replay.beta", 1.5, "replay.beta=1.5 must be in [0, 1]"),
        ("learner.gamma", 0.0, "learner.gamma=0.0 must be in (0, 1]"),
        ("num_threads", 0, "num_threads=0 must be in [1, 256]"),
        ("network.dense_reward_bound", 0.0, "network.dense_reward_bound=0.0 must be > 0 (or null)"),
        ("collector.env_threads", 0, "collector.env_threads=0 must be in [1, 256] (or null)"),
    ],
)
def test_a_fields_declared_range_gives_the_message_naming_it_and_its_bound(name, value, message):
    group, _, field = name.rpartition(".")
    overrides = {group: {field: value}} if group else {field: value}
    with pytest.raises(ValueError) as err:
        make_config(**overrides)
    assert message in str(err.value)


#: The ranges validate checked from hand-written lists before they moved onto the declarations.
OLD_RANGES = {
    **dict.fromkeys(
        (
            "collector.total_frames collector.frames_per_batch collector.num_workers "
            "collector.weight_sync_every replay.batch_size replay.buffer_size replay.n_steps "
            "network.num_atoms learner.target_update_period gentleness.dynamics_target_period "
            "gentleness.penalty_target_period gentleness.ensemble_size gentleness.model_hidden "
            "gentleness.model_batch_size gentleness.model_buffer_size logging.eval_every_frames "
            "logging.log_every_updates logging.checkpoint_every_frames num_threads "
            "collector.num_envs collector.env_threads"
        ).split(),
        ">= 1",
    ),
    **dict.fromkeys(
        (
            "collector.init_random_frames gentleness.reward_delay logging.eval_episodes "
            "collector.sigma learner.policy_noise learner.utd_ratio gentleness.surprise_scale "
            "gentleness.dynamics_surprise_scale gentleness.icm_eta"
        ).split(),
        ">= 0",
    ),
    **dict.fromkeys(
        (
            "learner.lr_actor learner.lr_critic gentleness.lr_model collector.cpus_per_worker "
            "collector.memory_per_worker_gb network.dense_reward_bound env.force_scale "
            "network.penalty_surprise_bound"
        ).split(),
        "> 0",
    ),
    # a micronewton at least: below, its unit underflows float32 (issue 63)
    "gentleness.tolerance": ">= 1e-06",
    "learner.gamma": "(0, 1]",
    "replay.alpha": "[0, 1]",
    "replay.beta": "[0, 1]",
}


#: The largest value of every size (issue 32: none unbounded; what each allows is in groups.py),
#: declared as the top of its field's range.
SIZE_LIMITS = {
    "num_threads": 256, "collector.num_workers": 512, "collector.cpus_per_worker": 256,
    "collector.memory_per_worker_gb": 1024, "collector.num_envs": 256,
    "collector.env_threads": 256, "collector.total_frames": 10**10,
    "collector.frames_per_batch": 100_000, "collector.init_random_frames": 10**10,
    "replay.buffer_size": 10**7, "replay.batch_size": 65536, "replay.n_steps": 100,
    "network.actor_hidden": 4096, "network.critic_hidden": 4096, "network.num_atoms": 1001,
    "gentleness.ensemble_size": 32, "gentleness.model_hidden": 2048,
    "gentleness.model_batch_size": 65536, "gentleness.model_buffer_size": 10**7,
    "logging.eval_episodes": 256, "gentleness.multiplier_episodes": 256,
}  # fmt: skip
#: Ranges that end at a number that is not a size (a share, a discount).
_NOT_SIZES = ("replay.alpha", "replay.beta", "learner.gamma")
#: The tops of values that are not sizes (config/limits.py says why each): the seed (numpy's
#: range less the offsets a run adds), a force, weights and scales, PID gains, a period.
VALUE_LIMITS = {
    "seed": 2**31 - 1, "gentleness.tolerance": 1e6, "gentleness.surprise_scale": 1e6,
    "gentleness.dynamics_surprise_scale": 1e6, "gentleness.icm_eta": 1e6,
    "gentleness.multiplier_gains": 1e3, "gentleness.multiplier_period": 10**10,
    "gentleness.multiplier_integral_max": 1e6, "gentleness.multiplier_base": 1e6,
    "gentleness.cost_limit": 10**10, "gentleness.cost_gains": 1e3,
    "gentleness.cost_warmup_frames": 10**10, "gentleness.cost_multiplier_max": 1e6,
    "gentleness.cost_period": 10**10,
}  # fmt: skip


def _declared() -> dict[str, Range]:
    return {n: f.metadata["bounds"] for n, f in iter_fields(TrainConfig) if f.metadata["bounds"]}


def test_the_declared_ranges_are_the_ones_validate_checked_before():
    """The bottoms are those of the hand-written lists; the tops those of :data:`SIZE_LIMITS`."""
    since = {  # declared with their fields (>= 0 per gain, >= 1 step, >= 0, >= 0, [0, 256])
        "gentleness.multiplier_gains",
        "gentleness.multiplier_period",
        "gentleness.multiplier_integral_max",
        "gentleness.multiplier_base",
        "gentleness.multiplier_episodes",
        "seed",  # [0, 2**31 - 1]: checked by a rule before (seed < 2**32)
        # Method IV's Lagrangian, declared with their fields
        "gentleness.cost_limit",
        "gentleness.cost_gains",
        "gentleness.cost_warmup_frames",
        "gentleness.cost_period",
        "gentleness.cost_multiplier_max",
    }
    low = {
        n: (b.low, b.low_open)
        for n, b in _declared().items()
        if n not in SIZE_LIMITS and n not in since
    }
    old = {n: (r.low, r.low_open) for n, r in map(lambda n: (n, Range.parse(OLD_RANGES[n])), low)}
    assert set(_declared()) == set(OLD_RANGES) | since | {
        "network.actor_hidden",
        "network.critic_hidden",
    }
    assert low == old
    top = {n: b.high for n, b in _declared().items() if b.high < float("inf")}
    values = {n: v for n, v in top.items() if n in VALUE_LIMITS}
    assert values == VALUE_LIMITS
    sizes = {n: v for n, v in top.items() if n not in _NOT_SIZES and n not in VALUE_LIMITS}
    assert sizes == SIZE_LIMITS


def _overrides(name: str, value: object) -> dict:
    group, _, field = name.rpartition(".")
    return {group: {field: value}} if group else {field: value}


@pytest.mark.parametrize("name", sorted(OLD_RANGES))
def test_a_value_just_outside_a_declared_range_is_refused(name):
    bounds = _declared()[name]
    outside = int(bounds.low if bounds.low_open else bounds.low - 1)  # an int fits float fields
    with pytest.raises(ValueError) as err:
        make_config(**_overrides(name, outside))
    assert f"{name}={outside} must be {bounds.describe()}" in str(err.value)


@pytest.mark.parametrize("name", sorted(SIZE_LIMITS))
def test_a_size_just_past_its_limit_is_refused_naming_the_limit(name):
    bounds, above = _declared()[name], int(SIZE_LIMITS[name]) + 1
    value = [above] if name.endswith("_hidden") and "model" not in name else above
    with pytest.raises(ValueError) as err:
        make_config(**_overrides(name, value))
    shown = f"{name}={value}: each value" if isinstance(value, list) else f"{name}={value}"
    assert f"{shown} must be {bounds.describe()}" in str(err.value)


def test_a_new_declaration_is_checked_without_being_listed():
    @dataclasses.dataclass
    class Probe:
        count: int = setting(3, "a count", bounds=">= 1")
        share: float = setting(0.5, "a share", bounds="(0, 1)")
        mode: str = setting("a", "a mode", choices=("a", "b"))

    assert declared_problems(Probe()) == []
    assert declared_problems(Probe(count=0, share=1.0, mode="c"), "probe.") == [
        "probe.count=0 must be >= 1",
        "probe.share=1.0 must be in (0, 1)",
        "probe.mode='c' is not one of ['a', 'b']",
    ]


@pytest.mark.parametrize(
    ("text", "inside", "outside"),
    [(">= 1", [1, 5], [0.5, -1]), ("> 0", [1e-9], [0, -1]), ("(0, 1]", [1, 0.5], [0, 1.01]),
     ("[0, 1]", [0, 1], [-0.1, 1.1]), ("< 2", [1.9], [2])],
)  # fmt: skip
def test_ranges_parse_as_written(text, inside, outside):
    bounds = Range.parse(text)
    assert all(v in bounds for v in inside) and not any(v in bounds for v in outside)


def test_an_unreadable_range_is_refused_at_declaration():
    with pytest.raises(ValueError, match="range 'positive' is not"):
        setting(1, "x", bounds="positive")


def test_the_ray_rules_have_one_source_for_the_config_and_the_collector():
    uneven = CollectorConfig(kind="ray", num_workers=3, frames_per_batch=100)
    (problem,) = ray_problems(uneven)
    assert "collector.frames_per_batch=100 must be a multiple of collector.num_workers=3" in problem
    with pytest.raises(ValueError) as err:
        make_config(collector={"kind": "ray", "num_workers": 3, "frames_per_batch": 100})
    assert problem in str(err.value)
    # make_ray_collector refuses the same settings before it touches Ray.
    with pytest.raises(ValueError) as err:
        make_ray_collector([object] * 3, None, frames_per_batch=100, total_frames=300,
                           init_random_frames=0)  # fmt: skip
    assert problem in str(err.value)
    with pytest.raises(ValueError, match=r"collector.cpus_per_worker=0 must be in \(0, 256\]"):
        make_ray_collector([object] * 2, None, frames_per_batch=100, total_frames=300,
                           init_random_frames=0, cpus_per_worker=0)  # fmt: skip
    with pytest.raises(
        ValueError,
        match=r"collector.ray_address='ray://head:x': port 'x' is not a number in \[1, 65535\]",
    ):
        make_ray_collector([object] * 2, None, frames_per_batch=100, total_frames=300,
                           init_random_frames=0, address="ray://head:x")  # fmt: skip
