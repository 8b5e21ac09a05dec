"""``gentlerl suite run`` (apps.suite, apps.suite_files): a suite file's cells trained on the toy
env, each cell's seeds one seed group, one results.csv; every refusal before any folder."""

import csv
import shutil
from pathlib import Path

import pytest

from gentlerl import cli
from gentlerl.analysis.results import RESULT_COLUMNS, read_results
from gentlerl.apps.suite import RESULTS, SuiteRefused, code_version, plan_suite, run_suite
from gentlerl.apps.suite_files import load_suite
from tests.helpers import files_under, toy_env

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "tests" / "apps" / "suite_example" / "toy.yaml"
AFTER_FIX = ROOT / "experiments" / "suites" / "after_fix.yaml"


def _suite_file(tmp_path: Path, body: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(body)
    return path


def _toy_body(variants: str, seeds: str = "[0, 1]") -> str:
    """The example suite's settings with other ``variants:`` (a YAML mapping's lines)."""
    text = EXAMPLE.read_text()
    head = text[: text.index("variants:")].replace("seeds: [0, 1]", f"seeds: {seeds}")
    return head + "variants:\n" + variants


@pytest.fixture(scope="module")
def toy_suite(tmp_path_factory):
    """The committed example (2 cells x 2 seeds, 600 frames) run once on the toy env."""
    out = tmp_path_factory.mktemp("suite") / "toy"
    lines: list[str] = []
    rows = run_suite(load_suite(EXAMPLE), out, env_factory=toy_env, echo=lines.append)
    return out, rows, lines


def test_each_cell_trains_its_seeds_as_one_group_and_writes_a_row_per_run(toy_suite):
    out, rows, lines = toy_suite
    assert [(r["cell"], r["seed"]) for r in rows] == [
        ("toy/r", 0), ("toy/r", 1), ("toy/r+rf+rsp", 0), ("toy/r+rf+rsp", 1),
    ]  # fmt: skip
    assert read_results(out / RESULTS) == rows
    with (out / RESULTS).open() as f:
        assert tuple(next(csv.reader(f))) == RESULT_COLUMNS
    for row in rows:
        run = out / row["cell"] / f"seed{row['seed']}"
        assert (run / "DONE").exists()
        assert row["suite"] == "toy" and row["task"] == "toy" and row["grouped"] == 1
        assert row["frames"] == 600  # 6 batches of 100: the final evaluation at total_frames
        assert 0.0 <= row["success_rate"] <= 1.0 and 0.0 <= row["broken_rate"] <= 1.0
        assert row["max_impact"] > 0.0 and row["wall_s"] > 0.0
        assert row["version"] == code_version()["version"] and row["commit"]
    # a seed group: both seeds of a cell logged one clock; the two cells did not
    assert rows[0]["wall_s"] != rows[2]["wall_s"]
    # one progress line before and two after each cell
    assert [line.split(":")[0] for line in lines] == ["[1/2] toy/r"] * 3 + [
        "[2/2] toy/r+rf+rsp"
    ] * 3
    assert "as one seed group, 600 frames" in lines[0] and "max impact" in lines[2]


def test_a_rerun_trains_nothing_and_keeps_the_rows(toy_suite, tmp_path):
    out, rows, _ = toy_suite
    copy = tmp_path / "toy"
    shutil.copytree(out, copy)
    before = {p: p.stat().st_mtime_ns for p in copy.rglob("*") if p.name != RESULTS}
    lines: list[str] = []
    again = run_suite(load_suite(EXAMPLE), copy, env_factory=toy_env, echo=lines.append)
    assert again == rows
    assert {p: p.stat().st_mtime_ns for p in copy.rglob("*") if p.name != RESULTS} == before
    assert all("finished earlier (DONE), not run again" in line for line in lines[::2])
    # the results file lost: rebuilt from the run directories, the same numbers
    (copy / RESULTS).unlink()
    rebuilt = run_suite(load_suite(EXAMPLE), copy, env_factory=toy_env, echo=lambda _: None)
    keep = ("frames", "return", "success_rate", "broken_rate", "max_impact", "wall_s")
    assert [{k: r[k] for k in keep} for r in rebuilt] == [{k: r[k] for k in keep} for r in rows]


def test_cells_and_dry_run_choose_what_runs_and_write_nothing(tmp_path):
    suite = load_suite(EXAMPLE)
    lines: list[str] = []
    assert run_suite(suite, tmp_path / "out", ["*/r+rf*"], dry_run=True, echo=lines.append) == []
    assert len(lines) == 1 and lines[0].startswith("[1/1] toy/r+rf+rsp: would train seeds [0, 1]")
    assert not (tmp_path / "out").exists()
    with pytest.raises(SuiteRefused, match=r"--cells \['touch/\*'\] matches none"):
        plan_suite(suite, tmp_path / "out", ["touch/*"])


def test_a_steered_cell_runs_its_seeds_one_by_one(tmp_path):
    """A seed group batches one penalty weight: gentleness.multiplier's seeds train alone."""
    body = _toy_body(
        "  constrained: [variant=r+rf, gentleness.tolerance=2.0, gentleness.multiplier=pid,"
        " gentleness.multiplier_base=0.0]\n"
    )
    rows = run_suite(
        load_suite(_suite_file(tmp_path, body)), tmp_path / "out", env_factory=toy_env,
        echo=lambda _: None,
    )  # fmt: skip
    assert [(r["cell"], r["seed"], r["grouped"]) for r in rows] == [
        ("toy/constrained", 0, 0), ("toy/constrained", 1, 0),
    ]  # fmt: skip
    assert rows[0]["wall_s"] != rows[1]["wall_s"]  # each seed its own clock


def test_every_cells_refusal_is_one_line_before_any_folder(tmp_path, capsys):
    body = _toy_body(
        "  r: [variant=r]\n"
        "  bad: [variant=r, replay.batch_size=0]\n"
        "  worse: [variant=r+rf+rsp, collector.frames_per_batch=-3]\n"
    )
    path = _suite_file(tmp_path, body)
    out = tmp_path / "out"
    assert cli.main(["suite", "run", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert [line.split(": ")[:2] for line in err] == [["gentlerl suite", "error"]] * 2
    assert "cell toy/bad: " in err[0] and "replay.batch_size" in err[0]
    assert "cell toy/worse: " in err[1] and "frames_per_batch" in err[1]
    assert not out.exists()


def test_an_interrupted_group_and_another_suites_results_are_refused(toy_suite, tmp_path):
    out, _, _ = toy_suite
    copy = tmp_path / "toy"
    shutil.copytree(out, copy)
    (copy / "toy" / "r" / "seed1" / "DONE").unlink()  # seed 1 did not finish
    (copy / RESULTS).write_text((copy / RESULTS).read_text().replace("\ntoy,", "\nother,"))
    before = files_under(copy)
    with pytest.raises(SuiteRefused) as refused:
        run_suite(load_suite(EXAMPLE), copy, env_factory=toy_env)
    problems = refused.value.problems
    assert len(problems) == 2
    assert "holds the rows of suite 'other': give 'toy' its own --out" in problems[0]
    assert problems[1].startswith("cell toy/r: ") and "remove the folder" in problems[1]
    assert files_under(copy) == before


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("seeds: [0]\ntasks: {t: [task=touch]}\nvariants: {r: [variant=r]}\nfoo: 1\n",
         "unknown keys ['foo']"),
        ("seeds: [0, 0]\ntasks: {t: [task=touch]}\nvariants: {r: [variant=r]}\n",
         "`seeds:` must be different"),
        ("seeds: [true]\ntasks: {t: [task=touch]}\nvariants: {r: [variant=r]}\n",
         "`seeds:` must be a list of integers"),
        ("seeds: [0]\ntasks: {../x: [task=touch]}\nvariants: {r: [variant=r]}\n",
         "'../x' is not a label"),
        ("seeds: [0]\ntasks: {t: [seed=3]}\nvariants: {r: [variant=r]}\n",
         "tasks.t: 'seed=3': seed is set per seed"),
        ("seeds: [0]\ntasks: {t: [hydra.run.dir=x]}\nvariants: {r: [variant=r]}\n",
         "tasks.t: --set 'hydra.run.dir=x': unknown key"),
        ("seeds: [0]\ntasks: {t: [task=touch]}\nvariants: {r: [variant=r]}\n"
         "cells: [{task: t, variant: q}]\n", "not both declared"),
        ("seeds: [0]\ntasks: {t: [task=touch]}\nvariants: {r: variant=r}\n",
         "expected a list of FIELD=VALUE strings"),
        ("seeds: [0]\ntasks: {t: [collector.kind=ray]}\nvariants: {r: [variant=r]}\n",
         "does not choose where its runs execute"),
    ],
)  # fmt: skip
def test_a_suite_files_refusal_names_the_file_and_what_is_wrong(tmp_path, body, message):
    path = _suite_file(tmp_path, body)
    with pytest.raises(ValueError, match="s.yaml: ") as refused:
        load_suite(path)
    assert message in str(refused.value) and "\n" not in str(refused.value)


def test_the_after_fix_suite_plans_its_fifteen_cells():
    """The issue's re-measure: 5 tasks x (r, r+rf+rsp, the constrained baseline), 3 seeds; the
    three finger tasks at the one tolerance 17.4 N."""
    suite = load_suite(AFTER_FIX)
    assert suite.name == "after_fix" and suite.seeds == (0, 1, 2)
    plans = plan_suite(suite, ROOT / "runs-that-do-not-exist")
    frames = {p.cell.task: p.cfgs[0].collector.total_frames for p in plans}
    assert frames == {
        "touch": 30000, "fragile": 30000, "finger-turn_easy": 100000, "finger-spin": 50000,
        "finger-turn_hard": 100000,
    }  # fmt: skip
    assert len(plans) == 15
    assert {p.cfgs[0].gentleness.tolerance for p in plans if "finger" in p.cell.task} == {17.4}
    base = {p.cell.name: p.cfgs[0].gentleness.multiplier_base for p in plans}
    assert [p.cell.variant for p in plans[:3]] == ["r", "r+rf+rsp", "constrained"]
    assert [p.grouped for p in plans[:3]] == [True, True, False]
    assert base["touch/constrained"] == 0.0 and plans[2].cfgs[0].variant == "r+rf"
    assert {str(c.run_dir) for p in plans for c in p.cfgs} >= {
        str(ROOT / "runs-that-do-not-exist" / "finger-spin" / "constrained" / "seed2")
    }


def test_export_writes_each_finished_hand_runs_actor_in_one_command(toy_suite, tmp_path, capsys):
    """``--export DIR``: the shipped policies from the suite's runs (the toy suite's task ``toy``
    trains ``task=touch``), each the final actor of its run, under its cell's folder names."""
    from gentlerl.apps.suite import main
    from gentlerl.training.checkpoint import load_checkpoint

    out, rows, _ = toy_suite
    copy = tmp_path / "toy"
    shutil.copytree(out, copy)
    policies = tmp_path / "policies"
    assert main(["run", str(EXAMPLE), "--out", str(copy), "--export", str(policies)]) == 0
    written = sorted(p.relative_to(policies).as_posix() for p in policies.rglob("*.pt"))
    assert written == [
        "toy/r+rf+rsp/seed0.pt", "toy/r+rf+rsp/seed1.pt", "toy/r/seed0.pt", "toy/r/seed1.pt",
    ]  # fmt: skip
    for name in written:
        config = load_checkpoint(policies / name)["config"]
        assert config["task"] == "touch"
        assert f"{config['variant']}/seed{config['seed']}.pt" == name.removeprefix("toy/")
    assert capsys.readouterr().out.splitlines()[-1] == f"4 policies under {policies}"


def test_export_names_a_policy_by_its_cells_folder_and_skips_an_unfinished_run(toy_suite, tmp_path):
    """A steered cell's runs are ``r+rf`` in their configs and ``constrained`` in the suite: the
    policy takes the cell's name; a run without ``DONE`` is not exported."""
    from gentlerl.apps.export import export_suite_runs

    out, _, _ = toy_suite
    copy = tmp_path / "toy"
    shutil.copytree(out / "toy" / "r", copy / "touch" / "constrained")
    shutil.copytree(out / "toy" / "r", copy / "touch" / "stopped")
    (copy / "touch" / "stopped" / "seed0" / "DONE").unlink()
    written = export_suite_runs(copy, tmp_path / "p")
    assert sorted(p.relative_to(tmp_path / "p").as_posix() for p in written) == [
        "touch/constrained/seed0.pt", "touch/constrained/seed1.pt", "touch/stopped/seed1.pt",
    ]  # fmt: skip
    assert written[tmp_path / "p" / "touch" / "stopped" / "seed1.pt"] == (
        copy / "touch" / "stopped" / "seed1" / "checkpoint.pt"
    )


def test_export_and_dry_run_together_are_refused_in_one_line(tmp_path, capsys):
    from gentlerl.apps.suite import main

    args = ["run", str(EXAMPLE), "--out", str(tmp_path / "o"), "--dry-run", "--export", "p"]
    with pytest.raises(SystemExit):
        main(args)
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--export writes policies; a --dry-run writes nothing" in err
    assert not (tmp_path / "o").exists() and not Path("p").exists()
