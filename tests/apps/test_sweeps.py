"""Local sweep runner: grid expansion, resumability, and one real (tiny) recipe run."""

import re
from pathlib import Path

import pytest
import yaml

from gentlerl.apps.grid import expand, restrict, run_grid
from gentlerl.apps.sweep_files import load_sweep
from gentlerl.apps.sweeps import main
from gentlerl.config.presets import SCALES
from gentlerl.training.config import make_config

SWEEPS = Path(__file__).resolve().parents[2] / "recipes" / "sweeps"
TINY = [
    "collector.total_frames=300", "collector.init_random_frames=200",
    "collector.frames_per_batch=100", "replay.batch_size=16", "logging.eval_episodes=1",
    "logging.eval_every_frames=300", "logging.checkpoint_every_frames=300",
    "logging.wandb_mode=disabled", "logging.progress=false", "network.actor_hidden=[16]",
    "network.critic_hidden=[16]", "gentleness.model_hidden=8",
]  # fmt: skip


def test_paper_sweeps_expand_to_the_expected_grids(tmp_path):
    # touch / fragile: 4 variants without penalty surprise + r+rf+rsp x 3 lambda'_2, x 5 seeds.
    for name, n in (("fig4_touch", 35), ("fig4_fragile", 35), ("fig3_noreward_impacts", 15)):
        runs = expand(load_sweep(SWEEPS / f"{name}.yaml"), tmp_path)
        assert len(runs) == n
        assert len({r.run_dir for r in runs}) == n
    names = [r.run_dir.name for r in expand(load_sweep(SWEEPS / "fig4_touch.yaml"), tmp_path)]
    assert "task-touch_variant-r+rf+rsp_lam_prime-2-1.5_seed-0" in names
    assert all("," not in n and "=" not in n and "[" not in n for n in names)


def test_only_cuts_the_grid_to_the_listed_values(tmp_path, capsys):
    grid = load_sweep(SWEEPS / "cpu" / "fig4_touch.yaml")
    cut = restrict(grid, ["variant=r+rf+rsp,rs", "seed=0,2"])
    assert cut["variant"] == ["r+rf+rsp"] and cut["seed"] == [0, 2]
    assert [r.run_dir.name for r in expand(cut, tmp_path)] == [
        "task-touch_variant-r+rf+rsp_lam_prime-2-2_seed-0",
        "task-touch_variant-r+rf+rsp_lam_prime-2-2_seed-2",
    ]
    with pytest.raises(ValueError, match="KEY one of"):
        restrict(grid, ["sigma=0.1"])
    with pytest.raises(ValueError, match="keeps none of variant's values"):
        restrict(grid, ["variant=rs"])
    sweep = str(SWEEPS / "cpu" / "fig4_touch.yaml")
    assert main([sweep, "--out", str(tmp_path), "--dry-run", "--only", "seed=1"]) == 0
    assert "5 runs: {'skipped': 0, 'done': 0, 'failed': 0, 'planned': 5}" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="--only 'seed'"):
        main([sweep, "--only", "seed"])


def test_bad_sweep_files_are_clear_errors(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("method: random\nparameters: {seed: {values: [0]}}\n")
    with pytest.raises(ValueError, match="only grid sweeps"):
        load_sweep(bad)
    bad.write_text("method: grid\nparameters: {seed: {min: 0}}\n")
    with pytest.raises(ValueError, match="needs `values:`"):
        load_sweep(bad)


def test_finished_runs_are_skipped_and_checkpointed_ones_resumed(tmp_path, monkeypatch):
    runs = expand({"variant": ["r", "r+rf+rsp"], "seed": [0]}, tmp_path)
    (runs[0].run_dir).mkdir(parents=True)
    (runs[0].run_dir / "DONE").write_text("done\n")
    (runs[1].run_dir).mkdir(parents=True)
    (runs[1].run_dir / "checkpoint.pt").write_bytes(b"x")
    calls = []
    monkeypatch.setattr("gentlerl.apps.grid._call", lambda cmd, log: calls.append(cmd) or 0)
    counts = run_grid(runs, workers=2)
    assert counts == {"skipped": 1, "done": 1, "failed": 0, "planned": 0}
    assert len(calls) == 1 and "resume=auto" in calls[0] and "variant=r+rf+rsp" in calls[0]


def test_a_real_tiny_grid_runs_the_recipe_and_then_skips_it(tmp_path):
    sweep = tmp_path / "tiny.yaml"
    sweep.write_text("method: grid\nparameters:\n  variant: {values: [r+rf+rsp]}\n"
                     "  gentleness.lam_prime: {values: [[2, 1.5]]}\n  seed: {values: [0]}\n")  # fmt: skip
    args = [str(sweep), "--out", str(tmp_path / "runs"), *sum((["--set", o] for o in TINY), [])]
    assert main(args) == 0
    run = tmp_path / "runs" / "tiny" / "variant-r+rf+rsp_lam_prime-2-1.5_seed-0"
    assert (run / "DONE").exists() and (run / "eval_episodes.csv").exists()
    config = yaml.safe_load((run / "config.yaml").read_text())
    assert config["gentleness"]["lam_prime"] == [2.0, 1.5]
    assert main(args) == 0  # second time: skipped, nothing re-run
    assert (run / "stdout.log").read_text().count("success_rate=") == 1


def _method_settings(method: str) -> dict[str, str]:
    """The ``--set KEY=VALUE`` pairs that ``recipes/grids/reproduce.sh --method METHOD`` adds."""
    text = (SWEEPS.parent / "grids" / "reproduce.sh").read_text()
    block = re.search(rf"^\s*{re.escape(method)}\) extra\+=\((.*?)\) ;;", text, re.M | re.S)
    assert block is not None, f"no --method {method} in reproduce.sh"
    return dict(pair.split("=", 1) for pair in re.findall(r"--set (\S+)", block.group(1)))


#: What the `paper` scale changes that is budget or size, not method: the cpu rows keep theirs.
BUDGET_AND_SIZES = {
    "collector.total_frames", "collector.init_random_frames", "replay.batch_size",
    "replay.buffer_size", "learner.utd_ratio", "learner.lr_actor", "learner.lr_critic",
    "network.actor_hidden", "network.critic_hidden", "gentleness.reward_delay",
    "gentleness.dynamics_target_period", "gentleness.penalty_target_period",
    "gentleness.model_batch_size", "gentleness.model_buffer_size",
    "logging.eval_every_frames", "logging.checkpoint_every_frames",
}  # fmt: skip


def test_the_published_method_switches_off_every_cpu_scale_change_as_the_paper_preset_does():
    # Every switch of the method where the `paper` scale differs from the cpu defaults must be
    # set by the row as published, to the preset's value (a new switch in the preset fails here
    # until reproduce.sh sets it or it is declared a budget or size).
    cpu = make_config().to_dict()
    differs = {
        f"{group}.{field}"
        for group, fields in SCALES["paper"].items()
        for field, value in fields.items()
        if yaml.safe_load(yaml.safe_dump(cpu[group][field]))
        != yaml.safe_load(yaml.safe_dump(value))
    }
    published = _method_settings("published")
    assert differs - BUDGET_AND_SIZES <= set(published), differs - BUDGET_AND_SIZES - set(published)
    assert "gentleness.rescore_surprise" in published  # the switch this test was written for
    for key, value in published.items():
        group, field = key.split(".")
        assert yaml.safe_load(value) == SCALES["paper"][group][field], (key, value)
    # Each ablation switches one setting, to the published value (nll-floor puts a floor back).
    ablations = {
        "no-recompute": "gentleness.rescore_surprise", "shared-support": "network.dense_reward_bound",
        "no-nll-floor": "gentleness.surprise_nll_floor", "no-support-cap": "network.bounded_support",
        "episodic": "learner.episodic_intrinsic", "unscaled-rs": "gentleness.dynamics_surprise_scale",
    }  # fmt: skip
    for method, key in ablations.items():
        assert _method_settings(method) == {key: published[key]}, method
    assert _method_settings("nll-floor") == {"gentleness.surprise_nll_floor": "0"}


def test_method_two_is_its_two_changes_and_each_is_a_valid_setting():
    bound, gain = _method_settings("rsp-bound"), _method_settings("information-gain")
    assert bound == {"network.penalty_surprise_bound": "3"}
    assert gain == {"gentleness.surprise_kind": "information_gain"}
    assert _method_settings("method2") == {**bound, **gain}
    cfg = make_config(network={"penalty_surprise_bound": 3.0},
                      gentleness={"surprise_kind": "information_gain"})  # fmt: skip
    assert (cfg.network.penalty_surprise_bound, cfg.gentleness.surprise_kind) == (
        3.0, "information_gain",
    )  # fmt: skip
