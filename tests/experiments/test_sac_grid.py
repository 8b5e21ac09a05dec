"""The SAC grid's pre-registered verdict (experiments/sac_grid/criteria.py) and its table
(experiments/sac_grid/table.py) from synthetic runs with known numbers."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from experiments.sac_grid.criteria import sac_verdict
from experiments.sac_grid.table import END, GENERATED, sac_markdown, sac_table
from tests.helpers import committed_blocks

ROOT = Path(__file__).resolve().parents[2]


def _sac(success: float, impact: float) -> dict[str, float]:
    return {"mean_success": success, "successful_impact": impact}


@pytest.mark.parametrize(
    ("task", "r", "rsp", "verdict"),
    [
        ("touch", _sac(1.0, 6.0), _sac(0.9, 4.0), "gentleness transfers"),
        ("touch", _sac(1.0, 6.0), _sac(0.5, 4.0), "gentler but less successful"),
        ("touch", _sac(1.0, 6.0), _sac(1.0, 5.0), "not gentler"),  # 5 > 0.75 x 6
        ("touch", _sac(1.0, 6.0), _sac(1.0, 4.5), "gentleness transfers"),  # 4.5 = 0.75 x 6
        ("fragile", _sac(0.3, 6.0), _sac(0.4, 1.0), "SAC does not learn the task at this budget"),
        ("fragile", _sac(0.3, 6.0), _sac(0.9, 2.0), "gentleness transfers; helps on the fragile block"),
        ("touch", _sac(0.3, 6.0), _sac(0.9, 2.0), "gentleness transfers"),  # touch: no fragile note
        (
            "touch", _sac(0.0, math.nan), _sac(1.0, 2.5),
            "more successful than r, which never succeeds; impacts not comparable",
        ),
        (
            "touch", _sac(0.6, math.nan), _sac(0.4, math.nan),
            "neither variant succeeds often enough to compare impacts",
        ),
    ],
)  # fmt: skip
def test_sac_verdict_applies_the_pre_registered_rule(task, r, rsp, verdict):
    assert sac_verdict(task, r, rsp) == verdict


def _sac_run(root, task, variant, seed, success, successful_impact):
    run = root / task / variant / f"seed{seed}"
    run.mkdir(parents=True)
    row = {
        "success_rate": success, "broken_rate": 0.0, "median_max_impact": 3.0,
        "p90_max_impact": 7.0, "median_max_impact_successful": successful_impact,
    }  # fmt: skip
    (run / "final_eval.json").write_text(json.dumps(row))


def test_the_sac_table_prints_each_row_and_the_verdict_of_each_task(tmp_path):
    for seed, (s_r, s_rsp) in enumerate([(1.0, 0.9), (0.8, 1.0), (0.9, 0.9)]):
        _sac_run(tmp_path, "touch", "r", seed, s_r, 6.0 + seed)
        _sac_run(tmp_path, "touch", "r+rf+rsp", seed, s_rsp, 3.0 + seed)
    out = sac_table(tmp_path)
    assert "| touch | `r` | 3 | 1.00 / 0.80 / 0.90 | 0.90 | 0.00 | 3.00 / 7.00 | 7.00 |" in out
    assert "| touch | `r+rf+rsp` | 3 | 0.90 / 1.00 / 0.90 | 0.93 |" in out
    assert out.rstrip().endswith("touch: gentleness transfers")  # 4 <= 0.75 x 7, 0.93 >= 0.72
    for seed in range(3):  # Method III's row: judged against r by the same rule
        _sac_run(tmp_path, "touch", "new", seed, 0.4, 2.0)
    out = sac_table(tmp_path)
    assert "touch: gentleness transfers" in out
    assert out.rstrip().endswith("touch, new: gentler but less successful")  # 0.4 < 0.72
    for seed in range(3):  # the fifth amendment's candidate (w = 1 + mu), judged alike
        _sac_run(tmp_path, "touch", "new_w1", seed, 0.9, 2.0)
    assert sac_table(tmp_path).rstrip().endswith("touch, new_w1: gentleness transfers")


def test_the_script_refuses_a_folder_without_runs_in_one_line(tmp_path):
    done = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "sac_grid" / "table.py"), str(tmp_path)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.count("\n") == 1
    assert "no <task>/<variant>/seed<k>/final_eval.json under" in done.stderr


def test_the_script_prints_the_table_run_from_anywhere(tmp_path):
    for seed in range(3):
        _sac_run(tmp_path, "touch", "r", seed, 1.0, 6.0)
        _sac_run(tmp_path, "touch", "r+rf+rsp", seed, 1.0, 3.0)
    done = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "sac_grid" / "table.py"), str(tmp_path)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(GENERATED.format(source=tmp_path.as_posix()) + "\n")
    assert done.stdout.endswith("touch: gentleness transfers\n\n" + END + "\n")


@pytest.mark.parametrize(
    ("path", "source", "block"),
    committed_blocks(GENERATED, END),
)
def test_each_committed_sac_table_is_what_its_runs_give(path, source, block, monkeypatch):
    """The committed copies of the runs' final evaluations regenerate the block word for word."""
    monkeypatch.chdir(ROOT)  # the folder as the command named it, from the repository's root
    assert Path(source).is_dir(), f"{path}: its SAC table names {source}, not committed"
    assert sac_markdown(Path(source)) == block, (
        f"{path}: rerun python experiments/sac_grid/table.py {source}"
    )


def test_the_readmes_sac_numbers_are_what_the_committed_runs_give():
    """The README's SAC sentence: touch's mean success and median successful max impact of
    ``r+rf+rsp`` and of plain SAC (``r``), as the committed final evaluations give them."""
    import re

    from experiments.sac_grid.table import load_sac_grid, sac_row

    runs = load_sac_grid(ROOT / "experiments" / "sac_grid" / "after_fix")
    rsp, r = (sac_row(runs["touch", v]) for v in ("r+rf+rsp", "r"))
    text = " ".join((ROOT / "README.md").read_text().split())
    stated = re.search(
        r"touch ([\d.]+) at ([\d.]+) N against plain SAC's ([\d.]+) at ([\d.]+) N", text
    )
    assert stated, "the README's SAC sentence is gone: update this test with it"
    measured = (
        rsp["mean_success"],
        rsp["successful_impact"],
        r["mean_success"],
        r["successful_impact"],
    )
    assert stated.groups() == tuple(f"{x:.2f}" for x in measured)
