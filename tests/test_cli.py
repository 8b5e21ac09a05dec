"""The ``gentlerl`` command: subcommands, their help (choices and defaults) and dispatch."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from gentlerl import cli
from gentlerl.apps import train as train_cli
from gentlerl.envs import TASKS
from gentlerl.rewards import VARIANTS
from tests.analysis.test_summary import _fake_run

ROOT = Path(__file__).resolve().parents[1]


def _help(capsys, *argv):
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, "--help"])
    assert exit_info.value.code == 0
    return " ".join(capsys.readouterr().out.split())


def test_the_package_installs_the_gentlerl_command():
    pyproject = (ROOT / "pyproject.toml").read_text()  # (tomllib is Python >= 3.11 only)
    assert '[project.scripts]\ngentlerl = "gentlerl.cli:main"\n' in pyproject


def test_top_level_help_lists_every_command(capsys):
    text = _help(capsys)
    for command in cli.COMMANDS:
        assert f" {command} " in text
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["fly"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'fly'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("command", "defaults"),
    [
        ("sweep", ["(default: runs/sweeps)", "(default: 1)", "{cpu,paper}"]),
        ("plot", ["(default: figures)", "(default: runs/sweeps)"]),
        ("video", ["(default: rollout.mp4)", "(default: 240)", "(default: 2)", "(default: 20)"]),
        ("evaluate", ["default: 50", "{explore,touch,fragile}", "default: 0"]),
        ("export", ["(default: docs/policies)", "(default: ['touch', 'fragile'])"]),
        ("table", ["RESULTS", "{sac,gentlebench,method3}", "the grid's --out folder"]),
        ("suite", ["ACTION", "run train every cell not yet done"]),
        ("seeds", ["SEED [SEED ...]", "(default: [])", "OUT/seed<SEED>"]),
    ],
)
def test_each_command_help_shows_its_options_with_defaults(capsys, command, defaults):
    text = _help(capsys, command)
    assert text.startswith(f"usage: gentlerl {command} ")
    for default in defaults:
        assert default in text


def test_train_help_lists_tasks_variants_scales_and_the_config_defaults():
    # A fresh process, as a user runs it (hydra's logging setup and pytest's capture disagree).
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    command = [sys.executable, "-m", "gentlerl", "train", "--help"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    text = " ".join(done.stdout.split())
    assert "task=touch the env task (touch: success is a fingerpad press > 5 N" in text
    assert "{" + ", ".join(TASKS) + "}" in text
    assert "scale=cpu preset applied under the overrides {cpu, paper, real}" in text
    assert "{" + ", ".join(VARIANTS) + "}" in text
    assert "collector.total_frames=100000" in text and "seed=0" in text


def test_plot_command_writes_the_figure_set(tmp_path, capsys):
    _fake_run(tmp_path / "runs", "r", 0, 2.0, (0.0, 1.0, 1.0), [1.0])
    assert cli.main(["plot", str(tmp_path / "runs"), "-o", str(tmp_path / "figs")]) == 0
    names = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert names == [
        "final_impacts.png",
        "impact_histograms.png",
        "learning_curves.png",
        "return_vs_impact.png",
        "reward_components.png",
        "summary.csv",
        "summary.md",
    ]


def test_train_command_runs_the_hydra_app_with_its_overrides(monkeypatch):
    seen = {}
    monkeypatch.setattr(
        train_cli, "main", lambda argv, prog: seen.update(argv=list(argv), prog=prog)
    )
    argv = list(sys.argv)
    assert cli.main(["train", "variant=r", "seed=3"]) == 0
    assert seen == {"argv": ["variant=r", "seed=3"], "prog": "gentlerl train"}
    assert sys.argv == argv  # handed to the app, not swapped into the process
