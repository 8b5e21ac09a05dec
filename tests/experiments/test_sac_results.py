"""experiments/sac_grid/results.py: a SAC run's final actor replays its recorded held-out
episodes and becomes a suite results row that ``gentlerl table`` renders."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from experiments.sac_grid.results import _recipe, grid_rows
from gentlerl.analysis.results import read_results
from gentlerl.analysis.results_table import results_markdown

ROOT = Path(__file__).resolve().parents[2]


def _run(root: Path, variant: str = "r", seed: int = 0) -> Path:
    """An untrained SAC actor saved as a finished run of the grid, with its final evaluation
    (2 held-out episodes) written as the recipe writes it."""
    sac = _recipe()
    run = root / "touch" / variant / f"seed{seed}"
    cfg = sac.parse([f"variant={variant}", f"seed={seed}", "hidden=[8]", "final_eval_episodes=2",
                     f"run_dir={run}"])  # fmt: skip
    run.mkdir(parents=True)
    torch.manual_seed(seed)
    actor = sac.make_sac_agent(sac.make_env_and_rewards(cfg)[0], cfg.hidden)[0]
    torch.save(actor.state_dict(), run / "actor.pt")
    from dataclasses import asdict

    from gentlerl.envs import make_env
    from gentlerl.training import evaluate_actor

    summary = evaluate_actor(lambda: make_env("touch"), actor, 2, sac.FINAL_EVAL_SEED)
    final = {"config": asdict(cfg), "frames": 30000, **summary}
    (run / "final_eval.json").write_text(json.dumps(final))
    return run


def test_a_run_becomes_a_row_with_its_episodes_mean_max_impact(tmp_path):
    run = _run(tmp_path)
    final = json.loads((run / "final_eval.json").read_text())
    (row,) = grid_rows(tmp_path, "sac_x")
    assert (row["suite"], row["cell"], row["variant"]) == ("sac_x", "touch/r", "r")
    assert (row["seed"], row["frames"], row["grouped"], row["wall_s"]) == (0, 30000, 0, None)
    assert row["success_rate"] == final["success_rate"]
    # the replay's mean return is the recorded one; of two episodes, the mean is the median
    assert row["return"] == pytest.approx(final["mean_return"])
    assert row["max_impact"] == pytest.approx(final["median_max_impact"])
    assert "**touch**, 30000 frames" in results_markdown([row], "x.csv")


def test_a_replay_that_differs_from_the_record_is_refused(tmp_path):
    run = _run(tmp_path)
    final = json.loads((run / "final_eval.json").read_text())
    final["median_max_impact"] += 0.5
    (run / "final_eval.json").write_text(json.dumps(final))
    with pytest.raises(ValueError, match="median_max_impact .* not the episodes it recorded"):
        grid_rows(tmp_path, "sac_x")


def test_the_script_writes_a_results_file_and_refuses_a_bad_suite_in_one_line(tmp_path):
    _run(tmp_path / "runs", variant="r+rf+rsp")
    script = [sys.executable, str(ROOT / "experiments/sac_grid/results.py"), str(tmp_path / "runs")]
    out = tmp_path / "out" / "results.csv"
    bad = subprocess.run([*script, "--suite", "a/b", "--out", str(out)], capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1 and "is not a label" in bad.stderr
    assert not out.parent.exists()
    done = subprocess.run([*script, "--suite", "sac_x", "--out", str(out)], capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    (row,) = read_results(out)
    assert row["cell"] == "touch/r+rf+rsp" and row["wall_s"] is None
