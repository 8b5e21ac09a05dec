"""A clean run prints its progress bar and its closing lines, nothing else: no library warnings,
no GLFW error on a headless machine, no ``nan`` for what an env does not define, impacts with
their unit, and where the run's files are."""

import os
import re
import shlex
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from gentlerl.apps.closing import closing_text
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards
from gentlerl.training.logging import force_unit

ROOT = Path(__file__).resolve().parents[2]
#: A machine without a display, as CI is, and with gentlerl's own choice of GL backend.
HEADLESS = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MUJOCO_GL")}
NOISE = re.compile(r"warn|error|traceback|nan\b", re.IGNORECASE)

#: tests/helpers.py's tiny run, shorter: the toy env, one evaluation, no wandb.
TOY_RUN = """
import sys
from tests.helpers import tiny_config, toy_env
from gentlerl.training import train
cfg = tiny_config(sys.argv[1], total_frames=300, init_random_frames=100, eval_every_frames=300)
print(train(cfg, toy_env))
"""

#: The same sizes as command-line overrides, for ``gentlerl train`` on a real env.
TINY_OVERRIDES = (
    "collector.total_frames=200 collector.frames_per_batch=100 collector.init_random_frames=100 "
    "replay.batch_size=16 network.actor_hidden=[16,16] network.critic_hidden=[16,16] "
    "network.num_atoms=11 gentleness.model_hidden=8 gentleness.reward_delay=10 "
    "logging.eval_episodes=1 logging.eval_every_frames=200 logging.wandb_mode=disabled"
).split()


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**HEADLESS, "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{ROOT}"}
    done = subprocess.run(args, env=env, cwd=cwd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return done


@pytest.mark.parametrize("variant", ["r+rf+rsp", "r+rf+rs"])  # penalty / dynamics targets
def test_constructing_the_rewards_warns_of_nothing(variant):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rewards = IntrinsicRewards(
            variant, GentlenessConfig(), obs_dim=63, action_dim=20, feature_shapes={"obs": [63]}
        )
        rewards.step(1)  # the target copies: TorchRL's HardUpdate, registered before any read
    assert [str(w.message) for w in caught] == []


def test_a_tiny_training_run_writes_no_warning(tmp_path):
    done = _run([sys.executable, "-c", TOY_RUN, str(tmp_path / "run")], tmp_path)
    assert not NOISE.search(done.stderr), done.stderr
    assert "WARNING" not in done.stdout and "success_rate" in done.stdout


@pytest.mark.parametrize("env_name", [None, "dm_control:finger-spin"])
def test_gentlerl_train_prints_the_bar_and_where_the_run_is(tmp_path, env_name):
    run = tmp_path / "run"
    env = [] if env_name is None else [f"env.name={env_name}"]
    done = _run(
        [sys.executable, "-m", "gentlerl", "train", f"run_dir={run}", *env, *TINY_OVERRIDES],
        tmp_path,
    )
    bar = [part for part in re.split(r"[\r\n]+", done.stderr) if part.strip()]
    assert bar and all("frame" in part and "|" in part for part in bar), done.stderr
    assert not NOISE.search(done.stderr) and not NOISE.search(done.stdout), done.stdout
    numbers, where, commands = done.stdout.splitlines()  # nothing else on stdout
    assert re.search(r"max_impact_mean=\d+\.\d{3} N ", numbers)
    # the hand defines success and broken; finger-spin does neither (no success_rate=nan)
    assert ("success_rate=" in numbers) == ("broken_rate=" in numbers) == (env_name is None)
    assert where.startswith(f"run directory {run}: policy best_policy.pt")
    assert (run / "best_policy.pt").is_file() and (run / "logs" / "scalars").is_dir()
    header = (run / "eval_episodes.csv").read_text().splitlines()[0]
    assert ("success" in header) == (env_name is None) and "nan" not in header
    plot, evaluate = commands.removeprefix("figures: ").split("    evaluate: ")
    assert evaluate == f"gentlerl evaluate {run / 'best_policy.pt'} --episodes 20"
    if env_name is None:  # the printed command works (once is enough)
        _run([sys.executable, "-m", *shlex.split(plot)], tmp_path)
        assert (run / "figures" / "learning_curves.png").is_file()


def test_closing_lines_give_the_scaled_force_unit_and_leave_out_nan():
    assert force_unit(1.0) == "N" and force_unit(0.01) == "100 N"
    summary = {"success_rate": float("nan"), "max_impact_mean": 2.8159, "return": 4.0}
    numbers = closing_text(summary, "runs/finger", force_unit(0.01)).splitlines()[0]
    assert numbers == "max_impact_mean=2.816 100 N return=4.000"  # an older run's NaN left out
