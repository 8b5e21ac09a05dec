"""``gentlerl train``'s command-line overrides: unknown fields, sizes past their limits, values of the
wrong type, unresolvable interpolations and removed fields are one-line refusals before anything is
written."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def test_train_refuses_unknown_fields_in_one_line(monkeypatch):
    from gentlerl.cli import main

    with pytest.raises(SystemExit, match=r"unknown config field\(s\) \['foo', 'network.bogus'\]"):
        main(["train", "foo=1", "network.bogus=2", "seed=1", "+env.kwargs.regime=easy"])


def _train(args: list[str]) -> str:
    """``gentlerl train ARGS`` in this process: its refusal (the one line ``SystemExit`` carries)."""
    from gentlerl.cli import main

    with pytest.raises(SystemExit) as err:
        main(["train", *args])
    return str(err.value.code)


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("collector.total_frames=99999999999999999999999", "must be in [1, 10000000000]"),
        ("network.actor_hidden=[200000,200000]", ": each value must be in [1, 4096]"),
        ("num_threads=100000", "num_threads=100000 must be in [1, 256]"),
        ("collector.num_envs=100000", "collector.num_envs=100000 must be in [1, 256]"),
        ("logging.eval_episodes=100000", "logging.eval_episodes=100000 must be in [0, 256]"),
        ("gentleness.ensemble_size=1000000", "gentleness.ensemble_size=1000000 must be in [1, 32]"),
        ("replay.buffer_size=1000000000000", "replay.buffer_size=1000000000000 must be in [1, 1"),
    ],
)
def test_sizes_past_their_limit_are_refused_before_anything_is_written(
    tmp_path, monkeypatch, override, message
):
    monkeypatch.chdir(tmp_path)
    refusal = _train([override])
    assert refusal.startswith("gentlerl train: error: invalid training config: ")
    assert message in refusal and "\n" not in refusal
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("override", "message"),
    [
        *[
            (f"collector.total_frames={v}", f"collector.total_frames={v} must be an integer")
            for v in ("abc", "1.5", "[1,2]", "{a: 1}", "true")
        ],
        ("env.force_scale=abc", "env.force_scale=abc must be a finite number"),
        ("network.actor_hidden=300", "network.actor_hidden=300 must be a list of integers"),
        ("network.actor_hidden=[a,b]", "network.actor_hidden=[a,b] must be a list of integers"),
        ("env.kwargs=5", "env.kwargs=5 must be a mapping"),
        ("resume=1", "resume=1 must be true, false or a string"),
        # an integer or a word is not a boolean (OmegaConf reads 1, 0, yes, on as one)
        *[
            (f"learner.compile={v}", f"learner.compile={v} must be true or false")
            for v in ("1", "0", "yes", "on", "2")
        ],
        ("logging.progress=0", "logging.progress=0 must be true or false"),
        # and a boolean is not a number
        ("seed=true", "seed=true must be an integer"),
        ("gentleness.tolerance=true", "gentleness.tolerance=true must be a finite number or null"),
        ("learner.gamma=false", "learner.gamma=false must be a finite number"),
        (
            "gentleness.multiplier_gains=[true,0,0]",
            "gentleness.multiplier_gains=[true,0,0] must be a list of 3 finite numbers",
        ),
        ("collector.overlap=1", "collector.overlap=1 must be true, false or a string"),
        ("run_dir=" + "x" * 5000, "(5000 chars): a folder name is 5000 bytes, over 255"),
        ("collector.ray_address=[::1]:1", "a string: collector.ray_address='[::1]:1')"),
        ("seed=[1", "seed=[1: "),
        ("+seed=1", "Could not append to config"),
    ],
)
def test_command_line_errors_are_one_line_naming_the_field_and_the_value(
    tmp_path, monkeypatch, capsys, override, message
):
    monkeypatch.chdir(tmp_path)
    refusal = _train([override])
    assert refusal.startswith("gentlerl train: error: ") and message in refusal
    assert "\n" not in refusal and len(refusal) < 300
    assert capsys.readouterr().err == ""  # hydra printed nothing of its own
    assert list(tmp_path.iterdir()) == []


def test_an_interpolation_that_cannot_resolve_is_one_line(tmp_path):
    # In a process of its own: an error resolving the config leaves objects that pytest's
    # capture of this process does not outlive.
    env = {**os.environ, "GENTLERL_DEBUG": "0"}
    env.pop("NOPE_UNSET", None)
    done = subprocess.run(
        [sys.executable, "-m", "gentlerl", "train", "run_dir=${oc.env:NOPE_UNSET}"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    lines = [line for line in done.stderr.splitlines() if "arn" not in line]  # not warnings
    assert done.returncode == 1 and lines[-1].startswith(
        "gentlerl train: error: run_dir=${oc.env:NOPE_UNSET}: "
    ), done.stderr
    assert "Environment variable 'NOPE_UNSET' not found" in lines[-1]
    assert "Traceback" not in done.stderr and "HYDRA_FULL_ERROR" not in done.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("~seed", "~seed: a config field cannot be removed"),
        ("~network", "~network: a config field cannot be removed"),
        ("hydra.run.dir=X", "hydra.run.dir=X: gentlerl sets hydra's folders from run_dir"),
        ("hydra.sweep.dir=X", "hydra.sweep.dir=X: gentlerl sets hydra's folders"),
    ],
)
def test_removing_a_field_or_moving_hydras_folder_is_refused(
    tmp_path, monkeypatch, override, message
):
    monkeypatch.chdir(tmp_path)
    assert message in _train([override])
    assert list(tmp_path.iterdir()) == []


def test_override_problems_names_each_refused_override_and_passes_the_rest():
    from gentlerl.apps.overrides import override_problems

    assert override_problems(["seed=3", "learner.gamma=0.9", "+env.kwargs.regime=easy"]) == []
    problems = override_problems(["nope=1", "~seed", "hydra.run.dir=/tmp/x", "seed=true"])
    assert len(problems) == 4
    assert problems[0].startswith("unknown config field(s) ['nope']")
    assert problems[1].startswith("~seed: a config field cannot be removed")
    assert (
        problems[2]
        == "hydra.run.dir=/tmp/x: gentlerl sets hydra's folders from run_dir; set run_dir"
    )
    assert problems[3].startswith("seed=true must be ")
