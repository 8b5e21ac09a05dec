"""``gentlerl seeds``: a seed group from the command line, its configs, folders and refusals."""

from pathlib import Path

import pytest

from gentlerl import cli
from gentlerl.apps import seeds as seeds_cli
from gentlerl.apps.seeds import group_configs
from gentlerl.config.limits import MAX_SEEDS
from gentlerl.training import seed_group
from gentlerl.training.seed_group import group_problems


def test_one_config_per_seed_equal_but_for_seed_and_folder(tmp_path):
    items = ["task=fragile", "collector.total_frames=600", "gentleness.lam_prime=[2,3]"]
    cfgs = group_configs([4, 1], items, tmp_path / "g")
    assert [c.seed for c in cfgs] == [4, 1]
    assert [Path(c.run_dir) for c in cfgs] == [tmp_path / "g" / "seed4", tmp_path / "g" / "seed1"]
    assert cfgs[0].task == "fragile" and cfgs[1].collector.total_frames == 600
    assert cfgs[0].gentleness.lam_prime == (2.0, 3.0)
    assert group_problems(cfgs) == []
    paper = group_configs([0, 1], ["scale=paper", "variant=r"])
    assert paper[0].scale == "paper" and paper[0].replay.batch_size == 256
    assert [c.run_dir for c in paper] == ["runs/touch/r/seed0", "runs/touch/r/seed1"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["0", "0"], "seeds must be one or more different integers, got [0, 0]"),
        (["0", "1", "--set", "seed=3"], "--set 'seed=3': seed is set per seed by gentlerl seeds"),
        (["0", "1", "--set", "run_dir=x"], "run_dir is set per seed by gentlerl seeds"),
        (["0", "1", "--set", "hydra.run.dir=x"], "unknown key 'hydra.run.dir'"),
        (["0", "1", "--set", "collector.total_frames=abc"], "must be an integer"),
        (["0", "1", "--set", "resume=true"], "--set 'resume=true': resume is set per seed"),
        # a word YAML reads as a boolean is not one on a command line (as gentlerl train)
        *[
            (["0", "1", "--set", f"learner.compile={v}"], f"learner.compile={v} must be true or")
            for v in ("yes", "on", "No", "OFF")
        ],
    ],
)
def test_a_refused_group_is_one_line_and_makes_no_folder(
    tmp_path, capsys, monkeypatch, argv, message
):
    trained = []
    monkeypatch.setattr(seed_group, "train_seeds", trained.append)  # a group taken: no training
    out = tmp_path / "group"
    assert cli.main(["seeds", *argv, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gentlerl seeds: error: ") and err.count("\n") == 1
    assert message in err
    assert not trained and not out.exists()


def test_a_run_dir_that_holds_a_checkpoint_is_refused_before_any_folder(tmp_path, capsys):
    (tmp_path / "g" / "seed1").mkdir(parents=True)
    (tmp_path / "g" / "seed1" / "checkpoint.pt").write_bytes(b"")
    assert cli.main(["seeds", "0", "1", "--out", str(tmp_path / "g")]) == 1
    assert "holds a checkpoint: a seed group does not resume" in capsys.readouterr().err
    assert not (tmp_path / "g" / "seed0").exists()


def test_the_group_trains_and_each_seed_gets_its_closing_lines(tmp_path, capsys, monkeypatch):
    seen = []

    def fake(cfgs):
        seen.extend(cfgs)
        return [{"success_rate": 0.5 + c.seed / 10, "max_impact_mean": 1.25} for c in cfgs]

    monkeypatch.setattr(seed_group, "train_seeds", fake)
    summaries = seeds_cli.main(["0", "3", "--set", "variant=r", "--out", str(tmp_path)])
    assert [c.seed for c in seen] == [0, 3] and summaries[1]["success_rate"] == 0.8
    assert {c.resume for c in seen} == {"auto"}  # a group stopped before a checkpoint re-runs
    out = capsys.readouterr().out
    assert "seed 0: success_rate=0.500 max_impact_mean=1.250 N" in out
    assert "seed 3: success_rate=0.800" in out and str(tmp_path / "seed3") in out


def test_more_seeds_than_a_group_holds_are_refused_in_one_line_before_any_folder(
    tmp_path, capsys, monkeypatch
):
    trained = []
    monkeypatch.setattr(seed_group, "train_seeds", trained.append)
    out = tmp_path / "group"
    argv = ["seeds", *map(str, range(MAX_SEEDS + 1)), "--out", str(out)]
    assert cli.main(argv) == 1
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1 and f"{MAX_SEEDS + 1} seeds: a group holds at most {MAX_SEEDS}" in err
    )
    assert not trained and not out.exists()
