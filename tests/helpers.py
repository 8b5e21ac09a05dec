"""Helpers shared by test files of several packages: the tiny training config, the toy env's
factory, a run's logged scalar, a variant's reward transforms, a pressing rollout, and the hostile
input tests' sweep files, sensor map, policy files and minimal runs, and the generated blocks
committed in the README and docs."""

import csv
from pathlib import Path

import numpy as np
import torch

from gentlerl import keys
from gentlerl.analysis.results_table import block_pattern
from gentlerl.config import GentlenessConfig
from gentlerl.config.layout import RunLayout
from gentlerl.rewards import IntrinsicRewards
from gentlerl.training import make_config
from gentlerl.training.config import iter_fields
from tests.toy_env import ToyHandEnv

#: Small nets, few frames: a full loop (with model updates) in a few seconds.
TINY = dict(
    num_threads=1,  # tiny nets; 2 threads on a shared 2-core CPU is many times slower
    collector=dict(total_frames=1000, frames_per_batch=100, init_random_frames=200),
    replay=dict(batch_size=32),
    learner=dict(utd_ratio=0.5),
    network=dict(actor_hidden=(32, 32), critic_hidden=(32, 32), num_atoms=11),
    gentleness=dict(
        reward_delay=100,
        dynamics_target_period=20,
        penalty_target_period=10,
        model_hidden=16,
        model_batch_size=16,
    ),
    logging=dict(
        eval_every_frames=500,
        eval_episodes=2,
        log_every_updates=50,
        checkpoint_every_frames=500,
        wandb_mode="disabled",
        progress=False,
    ),
)


#: Field name -> its group, for the tests' short form ``tiny_config(path, total_frames=300)``.
GROUP_OF = {name.split(".")[1]: name.split(".")[0] for name, _ in iter_fields() if "." in name}


def tiny_config(run_dir: Path, **overrides):
    """:data:`TINY` with ``overrides`` on top: top-level fields, ``group={field: value}``, or a
    group's field by its name alone (``total_frames=300``)."""
    values = {k: dict(v) if isinstance(v, dict) else v for k, v in TINY.items()}
    for name, value in overrides.items():
        if isinstance(value, dict) and name not in GROUP_OF:
            values.setdefault(name, {}).update(value)
        elif name in GROUP_OF:
            values.setdefault(GROUP_OF[name], {})[name] = value
        else:
            values[name] = value
    return make_config(run_dir=str(run_dir), **values)


def toy_env():
    return ToyHandEnv(time_limit=50)


def read_scalar(run_dir: Path, name: str) -> list[tuple[int, float]]:
    path = RunLayout(run_dir).scalars / f"{name}.csv"
    return [(int(s), float(v)) for s, v in csv.reader(path.open())]


HAND_FEATURES = {keys.JOINT_POS: (24,), keys.JOINT_VEL: (24,), keys.TOUCH: (5, 3)}


def make_reward_transforms(variant, seed=0, hidden=128, **settings):
    """A variant's :class:`IntrinsicRewards` for the toy / hand env's sizes."""
    gentleness = GentlenessConfig(model_hidden=hidden, **settings)
    return IntrinsicRewards(
        variant, gentleness, obs_dim=63, action_dim=20, feature_shapes=HAND_FEATURES, seed=seed
    )


def pressing_rollout(env, steps=12):
    # Joint 1 moves +0.1 per step: it passes the wall at 0.5 after 5 steps, then presses with
    # fingertip 1 (only fingertip 0 ends the toy episode).
    action = torch.zeros(20)
    action[1] = 1.0
    return env.rollout(steps, policy=lambda td: td.set(keys.ACTION, action.expand(*td.shape, 20)))


def sweep_file(tmp_path: Path, body: str) -> str:
    """A sweep file holding ``body``: its path."""
    path = tmp_path / "evil.yaml"
    path.write_text(body)
    return str(path)


def files_under(root: Path) -> set[Path]:
    """Every path under ``root``: what a refusal must leave unchanged."""
    return {p for p in root.rglob("*")}


def linear_sensor_map(n_knots: int = 16):
    """A TouchSensorMap fitted to a linear sensor (raw = 1000 + 100 * force) and its forces."""
    from gentlerl.transforms import TouchSensorMap

    force = np.linspace(0, 20, 64)[:, None, None] * np.ones((1, 5, 1))
    sensor_map = TouchSensorMap(n_knots=n_knots)
    sensor_map.fit(1000 + 100 * force, force)
    return sensor_map, force


def policy_file(tmp_path: Path, hidden: list[int], weights_hidden: list[int]) -> Path:
    """A saved policy whose config says ``hidden`` and whose actor weights are ``weights_hidden``."""
    from gentlerl.models import make_actor
    from gentlerl.training.checkpoint import save_checkpoint
    from gentlerl.training.config import preset_config

    config = preset_config(network={"actor_hidden": hidden}).to_dict()
    actor = make_actor(10, 20, weights_hidden)
    path = tmp_path / "policy.pt"
    state = {"config": config, "obs_dim": 10, "action_dim": 20, "actor": actor.state_dict()}
    save_checkpoint(path, state)
    return path


def minimal_run(root: Path, seed: int = 0, scalars: str | None = "1000,0.5\n2000,0.7\n") -> Path:
    """A run folder with a config and (unless ``scalars`` is None) one eval scalar file."""
    import yaml

    run = root / f"seed{seed}"
    config = {"task": "touch", "variant": "r", "seed": seed, "collector": {}, "gentleness": {}}
    run.mkdir(parents=True)
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    if scalars is not None:
        (run / "logs" / "scalars" / "eval").mkdir(parents=True)
        (run / "logs" / "scalars" / "eval" / "success_rate.csv").write_text(scalars)
    return run


#: The repository's root.
ROOT = Path(__file__).resolve().parents[1]


def committed_blocks(first: str, last: str) -> list:
    """Every block from a ``first`` line (a template naming its ``{source}``) through its
    ``last`` line in the README and docs: ``(path, source, block)``, or one skipped parameter
    when none is committed yet (for ``pytest.mark.parametrize``)."""
    import pytest

    pattern = block_pattern(first, last)
    found = [
        (path, m["source"], m[0])
        for path in sorted([*ROOT.glob("*.md"), *ROOT.glob("docs/**/*.md")])
        for m in pattern.finditer(path.read_text())
    ]
    skip = pytest.mark.skip(reason="no such block committed yet")
    return found or [pytest.param(None, None, None, marks=skip)]
