"""recipes/sac_gentle.py: TorchRL's SAC with gentleness through the public API, on the hand."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest
import torch

RECIPES = Path(__file__).resolve().parents[2] / "recipes"
SAC_GRID = RECIPES.parent / "experiments" / "sac_grid" / "grid.sh"


def load(name: str):
    spec = importlib.util.spec_from_file_location(name, RECIPES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_a_tiny_sac_run_updates_the_models_with_the_learner_and_writes_its_evaluation(tmp_path):
    sac = load("sac_gentle")
    cfg = sac.parse(
        [
            "total_frames=800", "init_random_frames=400", "frames_per_batch=200",
            "batch_size=32", "hidden=[16,16]", "reward_delay=10", "eval_every_frames=400",
            "eval_episodes=1", "final_eval_episodes=2", f"run_dir={tmp_path}",
        ]
    )  # fmt: skip
    result = sac.train(cfg)
    # 0.25 updates per frame after the 400 random frames: 100 SAC and model updates
    assert result["updates"] == 100 and result["frames"] == 800
    written = json.loads((tmp_path / "final_eval.json").read_text())
    assert written["config"]["variant"] == "r+rf+rsp" and written["episodes"] == 2
    assert 0.0 <= written["success_rate"] <= 1.0 and written["median_max_impact"] >= 0.0
    actor = sac.make_sac_agent(sac.make_env_and_rewards(cfg)[0], cfg.hidden)[0]
    actor.load_state_dict(torch.load(tmp_path / "actor.pt"))  # the final actor, reloadable
    rows = (tmp_path / "evals.csv").read_text().splitlines()
    assert rows[0].startswith("frames,") and [r.split(",")[0] for r in rows[1:]] == ["400", "800"]


def _steered(run_dir: Path) -> list[str]:
    """A tiny SAC run of ``r+rf`` with a PID multiplier at a 0.05 N tolerance (every press is
    far above it), 200 random frames then 600 of learning."""
    return [
        "total_frames=800", "init_random_frames=200", "batch_size=32", "hidden=[16,16]",
        "reward_delay=10", "eval_every_frames=800", "eval_episodes=1", "final_eval_episodes=1",
        f"run_dir={run_dir}", "variant=r+rf", "tolerance=0.05", "multiplier=pid",
    ]  # fmt: skip


def test_the_sac_recipe_steers_the_summed_penalty_toward_the_tolerance(tmp_path):
    """multiplier=pid: the collected episodes (impacts far above a 0.05 N tolerance) raise the
    penalty's weight in the one reward SAC reads, once per 100 env steps after the random ones."""
    sac = load("sac_gentle")
    cfg = sac.parse([*_steered(tmp_path), "multiplier_period=100", "multiplier_integral_max=2"])
    result = sac.train(cfg)
    assert 1.0 < result["penalty_weight"]
    written = json.loads((tmp_path / "final_eval.json").read_text())
    assert written["penalty_weight"] == result["penalty_weight"]


def test_the_sac_recipe_can_steer_on_the_actors_noise_free_episodes(tmp_path, monkeypatch):
    """multiplier_episodes=2, period 200, base 0: each PID step reads two noise-free episodes
    of the current actor: the first batch after the random frames (400) only notes the frames,
    600 and 800 each step on 2 episodes of their own seed; none of the collected episodes."""
    sac = load("sac_gentle")
    cfg = sac.parse(
        [*_steered(tmp_path), "multiplier_period=200", "multiplier_base=0", "multiplier_episodes=2"]
    )
    calls = []
    real = sac.actor_episodes
    monkeypatch.setattr(sac, "actor_episodes", lambda *a, **k: calls.append(a[2:]) or real(*a, **k))
    multipliers = []
    real_steer = sac.steer
    monkeypatch.setattr(sac, "steer", lambda m, *a: multipliers.append(m) or real_steer(m, *a))
    result = sac.train(cfg)
    multiplier = multipliers[0]
    assert (multiplier.steps, multiplier.episodes, multiplier.base) == (2, 4, 0.0)
    assert [n for n, _ in calls] == [2, 2] and len({seed for _, seed in calls}) == 2
    assert result["penalty_weight"] == multiplier.weight


def test_the_sac_recipe_refuses_a_bad_setting_in_one_line(capsys):
    sac = load("sac_gentle")
    with pytest.raises(SystemExit, match="Key 'bogus' not in 'SACConfig'"):
        sac.parse(["bogus=1"])
    with pytest.raises(SystemExit, match="'abc'"):
        sac.parse(["seed=abc"])
    # the finding: seed=4294967295 passed and failed late, in numpy's seeding
    with pytest.raises(SystemExit, match=r"seed=4294967295 must be in \[0, 2147483647\]"):
        sac.parse(["seed=4294967295"])
    with pytest.raises(SystemExit, match=r"seed \+ 10000 \+ total_frames must be < 2\*\*32"):
        sac.parse(["seed=2147483647", "total_frames=4294967295"])


def test_the_sac_grid_passes_out_as_one_word_and_runs_nothing_it_names(tmp_path):
    """The finding: ``sac_grid.sh --out 'sg$(touch X)'`` ran the command (xargs ... sh -c)."""
    import os
    import subprocess

    stub = tmp_path / "bin"
    stub.mkdir()
    (stub / "python").write_text('#!/bin/sh\nprintf "%s\\n" "$@" >> "$ARGV_LOG"\n')
    (stub / "python").chmod(0o755)
    out = "sg$(touch X) with space"
    env = {**os.environ, "PATH": f"{stub}:{os.environ['PATH']}", "ARGV_LOG": str(tmp_path / "argv")}
    proc = subprocess.run(
        ["bash", str(SAC_GRID), "--out", out, "--workers", "2"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "X").exists()
    argv = (tmp_path / "argv").read_text().splitlines()
    assert f"run_dir={out}/touch/r/seed0" in argv and argv.count("seed=2") == 4
    assert argv[-2:] == [str(SAC_GRID.parent / "table.py"), out]  # then the table of the grid
    bad = subprocess.run(
        ["bash", str(SAC_GRID), "--workers", "0"],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 2 and "--workers must be a positive integer, got '0'" in bad.stderr
    (tmp_path / "argv").unlink()
    method3 = ["--tasks", "touch", "--variants", "r new new_w1", "--utd", "1", "--out", "m3"]
    proc = subprocess.run(
        ["bash", str(SAC_GRID), *method3],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    argv = (tmp_path / "argv").read_text().splitlines()
    assert argv.count("utd_ratio=1") == 9 and argv.count("task=fragile") == 0
    assert argv.count("variant=r+rf+rsp") == 6 and argv.count("multiplier_episodes=3") == 6
    # new is a plain Lagrangian (w = mu), new_w1 keeps the paper's weight as floor (w = 1 + mu)
    assert argv.count("multiplier_base=0.0") == 3 and argv.count("multiplier_base=1.0") == 3
    assert "run_dir=m3/touch/new/seed2" in argv and "run_dir=m3/touch/new_w1/seed0" in argv


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("total_frames=-1", r"total_frames=-1 must be in \[1, 10000000000\]"),
        ("utd_ratio=1e9", r"utd_ratio=1000000000.0 must be in \(0, 64\]"),
        ("utd_ratio=nan", r"utd_ratio=nan must be in \(0, 64\]"),
        ("task=../../../x", r"task='../../../x' is not one of"),
        ("batch_size=0", r"batch_size=0 must be in \[1, 65536\]"),
        ("hidden=[0]", r"hidden=\[0\] must list 1 to 8 layer sizes"),
        ("lr=nan", r"lr=nan must be in \(0, 1\]"),
        ("gamma=2", r"gamma=2.0 must be in \(0, 1\]"),
        ("reward_delay=-1", "reward_delay=-1 must be >= 0"),
        ("num_threads=0", r"num_threads=0 must be in \[1, 256\]"),
        ("multiplier=pid", "multiplier=pid steers toward the tolerance: set tolerance"),
        ("tolerance=0", r"tolerance=0.0 must be in \[1e-06, 1000000.0\]"),
        ("tolerance=1e-300", r"tolerance=1e-300 must be in \[1e-06, 1000000.0\]"),
        ("tolerance=1e300", r"tolerance=1e\+300 must be in \[1e-06, 1000000.0\]"),
        ("lam_prime=[0,2]", r"lam_prime=\(0.0, 2.0\) must be \[lambda_1 > 0"),
        ("multiplier_period=0", r"multiplier_period=0 must be in \[1, 10000000000\]"),
    ],
)
def test_the_sac_recipe_refuses_bad_values_before_any_folder(
    tmp_path, monkeypatch, override, message
):
    """The findings: these ran forever, made a folder outside runs/ or ended in a traceback."""
    monkeypatch.chdir(tmp_path)
    sac = load("sac_gentle")
    with pytest.raises(SystemExit, match=f"sac_gentle: {message}"):
        sac.parse([override])
    assert list(tmp_path.iterdir()) == []
