"""The commands refuse, in one line and before any work, what would hang or leave --out:
YAML aliases (a "billion laughs"), grids over the bound, sweep file names that are no folder
name, unbounded episode counts (issue 44's findings, each reproduced here)."""

import subprocess
import sys

import numpy as np
import pytest
import torch
import yaml

from gentlerl.apps.grid import MAX_GRID_POINTS, expand
from gentlerl.apps.sweep_files import load_sweep
from gentlerl.apps.video import MAX_VIDEO_EPISODES, MAX_VIDEO_STEPS, record_rollouts
from gentlerl.files import MAX_YAML_BYTES, load_yaml
from gentlerl.training.evaluation import MAX_EPISODES, check_episodes

#: The finding: a 471-byte sweep whose ten parameters share one ten-value alias (10^10 points).
ALIAS_SWEEP = "method: grid\nvalues: &v {values: [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]}\nparameters:\n" + (
    "".join(f"  {k}: *v\n" for k in ("seed", "collector.sigma", "replay.alpha", "replay.beta"))
)
LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{b}: &{b} [*{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}, *{a}]\n"
    for a, b in zip("abcdefgh", "bcdefghi", strict=True)
)


def test_load_yaml_refuses_aliases_and_oversized_text():
    assert load_yaml("a: [1, 2]\nb: {c: x}") == {"a": [1, 2], "b": {"c": "x"}}
    with pytest.raises(yaml.YAMLError, match=r"YAML aliases are not accepted \(\*a\)"):
        load_yaml(LAUGHS)
    with pytest.raises(yaml.YAMLError, match="over the 1,048,576 read"):
        load_yaml("#" * (MAX_YAML_BYTES + 1))


def test_load_yaml_reads_only_true_and_false_as_booleans():
    text = "a: [true, False, TRUE]\nb: [yes, no, on, off, y, n, Yes, OFF]\nc: 'true'"
    assert load_yaml(text) == {
        "a": [True, False, True],
        "b": ["yes", "no", "on", "off", "y", "n", "Yes", "OFF"],
        "c": "true",
    }


def test_an_alias_bomb_sweep_is_refused_at_once(tmp_path):
    sweep = tmp_path / "bomb.yaml"
    sweep.write_text(ALIAS_SWEEP)
    with pytest.raises(ValueError, match=r"bomb.yaml: not valid YAML \(YAML aliases are not"):
        load_sweep(sweep)


def test_an_alias_bomb_run_config_is_refused_by_plot(tmp_path):
    from gentlerl.analysis.runs import load_run

    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text("task: touch\nvariant: r\nseed: 0\n" + LAUGHS)
    with pytest.raises(ValueError, match="config.yaml: not valid YAML"):
        load_run(run)


def test_a_grid_over_the_bound_is_refused_before_it_is_expanded(tmp_path):
    grid = {f"g{i}": list(range(10)) for i in range(10)}  # 10^10 points
    with pytest.raises(ValueError, match=r"10 x 10 .* = 10,000,000,000 points, over 10,000"):
        expand(grid, tmp_path)
    assert len(expand({"seed": list(range(MAX_GRID_POINTS))}, tmp_path)) == MAX_GRID_POINTS


@pytest.mark.parametrize("name", ["...yaml", "${oc.env:HOME}.yaml", "a,b.yaml", ".hidden.yaml"])
def test_a_sweep_file_name_that_is_no_folder_name_is_refused(tmp_path, name):
    sweep = tmp_path / name
    sweep.write_text("method: grid\nparameters: {seed: {values: [0]}}\n")
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "gentlerl", "sweep", str(sweep), "--out", str(out), "--dry-run"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode != 0 and "cannot name its folder under --out" in proc.stderr
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == [name]


@pytest.mark.parametrize("bad", [0, -1, MAX_EPISODES + 1, 10**12, True, 2.0])
def test_episode_counts_are_bounded(bad):
    with pytest.raises(ValueError, match=r"episodes must be an integer in \[1, 10,000\]"):
        check_episodes(bad)
    assert check_episodes(MAX_EPISODES) == MAX_EPISODES


def test_evaluate_refuses_an_unbounded_episode_count_in_one_line(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "gentlerl", "evaluate", str(tmp_path / "p.pt"), "--episodes",
         str(10**12)], capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1
    assert "episodes must be an integer in [1, 10,000]" in proc.stderr


def test_video_refuses_too_many_episodes_and_caps_an_episode_that_never_ends():
    from gentlerl.apps.video import main

    with pytest.raises(SystemExit, match=rf"--episodes must be in \[1, {MAX_VIDEO_EPISODES}\]"):
        main(["policy.pt", "--episodes", "1000", "--out", "v.gif"])

    class Endless:
        """An env whose episodes never end (the finding: time_limit=1e9, no touch)."""

        steps = 0

        def reset(self):
            return {"touch": torch.zeros(5, 3)}

        def step(self, td):
            Endless.steps += 1
            nxt = {"touch": torch.zeros(5, 3), "success": False, "broken": False,
                   "done": torch.tensor(False)}  # fmt: skip
            return {**td, "next": nxt}

    import gentlerl.apps.video as video

    class Painter:
        def __init__(self, env):
            pass

        def paint(self, *args):
            pass

    env = Endless()
    env.render = lambda w, h: np.zeros((h, w, 3), np.uint8)
    original = video.ImpactPainter
    video.ImpactPainter = Painter
    try:
        frames = record_rollouts(env, lambda td: td, episodes=1, size=16, hold=0, panel=False)
    finally:
        video.ImpactPainter = original
    assert Endless.steps == MAX_VIDEO_STEPS and len(frames) == MAX_VIDEO_STEPS + 1
