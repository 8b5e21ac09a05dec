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


def _tampered(run: Path, **changes) -> None:
    final = json.loads((run / "final_eval.json").read_text())
    for key, value in changes.items():
        if key in final["config"] or key == "no_such":
            final["config"][key] = value
        else:
            final[key] = value
    (run / "final_eval.json").write_text(json.dumps(final))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        # the finding: a 1 kB final_eval.json asking for these sizes reached 6.9 GB
        ({"hidden": [40000, 40000]}, r"hidden=\[40000, 40000\] must list 1 to 8 layer sizes"),
        ({"seed": 7}, "config is task=touch variant=r seed=7, its folder touch/r/seed0"),
        ({"task": "fragile"}, "config is task=fragile .* its folder touch/r/seed0: not this"),
        ({"final_eval_episodes": 10**9}, r"final_eval_episodes=1000000000 must be in \[1, 10000\]"),
        ({"no_such": 1}, "its config is not the recipe's"),
        ({"hidden": "x"}, "its config is not the recipe's"),
        ({"success_rate": float("nan")}, r"'success_rate': nan.* must be finite numbers"),
        ({"frames": "30000"}, "must be finite numbers"),
    ],
)
def test_a_replayed_config_is_checked_against_its_folder_and_bounds_before_building(
    tmp_path, monkeypatch, changes, message
):
    import experiments.sac_grid.results as results

    run = _run(tmp_path)
    _tampered(run, **changes)
    built = []
    monkeypatch.setattr(results._recipe(), "make_sac_agent", lambda *a: built.append(a))
    with pytest.raises(ValueError, match=message) as err:
        grid_rows(tmp_path, "sac_x")
    assert "\n" not in str(err.value) and "final_eval.json" in str(err.value)
    assert built == []  # refused before any network was built


def test_a_run_folder_that_is_a_link_or_an_actor_of_other_sizes_is_refused(tmp_path):
    run = _run(tmp_path / "a")
    (tmp_path / "b" / "touch").mkdir(parents=True)
    (tmp_path / "b" / "touch" / "r").symlink_to(run.parent)
    with pytest.raises(ValueError, match="run folder=.* is a symbolic link"):
        grid_rows(tmp_path / "b", "sac_x")
    _tampered(run, hidden=[16])
    with pytest.raises(ValueError, match=r"actor.pt: not this config's actor \(Error"):
        grid_rows(tmp_path / "a", "sac_x")
