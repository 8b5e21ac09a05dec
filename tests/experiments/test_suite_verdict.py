"""The re-measure's verdict (experiments/suites/verdict.py): medians over seeds against ``r``,
GentleBench's thresholds, the goal counted over foreign tasks only (the hand's left out); and
every committed verdict block is what its CSV gives."""

from pathlib import Path

import pytest

from experiments.suites.verdict import END, GENERATED, verdict_markdown
from tests.helpers import committed_blocks

ROOT = Path(__file__).resolve().parents[2]


def _rows(task: str, variant: str, returns, impacts, frames: int = 50000) -> list[dict]:
    return [
        {"task": task, "variant": variant, "seed": s, "frames": frames, "return": r,
         "max_impact": i}
        for s, (r, i) in enumerate(zip(returns, impacts, strict=True))
    ]  # fmt: skip


def test_a_task_passes_at_0_8x_the_return_and_0_5x_the_impact_by_medians():
    rows = [
        # medians: r 110 at 12 N; r+rf+rsp 95 at 5 N (0.86x, 0.42x): passes; the outlier seed
        # (300, 50 N) moves no median
        *_rows("spin", "r", [100, 110, 120], [10, 12, 14]),
        *_rows("spin", "r+rf+rsp", [90, 95, 300], [4, 5, 50]),
        # 87 < 0.8 x 110 = 88: keeps no return; 6 N = 0.5 x 12 N: gentler
        *_rows("turn", "r", [100, 110, 120], [10, 12, 14]),
        *_rows("turn", "r+rf+rsp", [80, 87, 90], [5, 6, 7]),
        *_rows("touch", "r", [1, 1, 1], [6, 7, 8], 30000),
        *_rows("touch", "r+rf+rsp", [1, 1, 1], [2, 2, 2], 30000),
    ]
    text = verdict_markdown(rows, "x.csv")
    lines = {ln.split(" | ")[0] + ln.split(" | ")[1]: ln for ln in text.splitlines() if "|" in ln}
    assert "| 0.86x | 0.42x | gentle and as good |" in lines["| spinr+rf+rsp (3)"]
    assert "110.0 / 12.0 N | 95.0 / 5.0 N" in lines["| spinr+rf+rsp (3)"]
    assert lines["| turnr+rf+rsp (3)"].endswith("| 0.79x | 0.50x | gentle but worse |")
    # the hand's task is left out: 1 of the 2 foreign tasks, the third could decide
    assert not any(key.startswith("| touch") for key in lines)
    assert "**undecided** — 1 of the 2 foreign tasks measured pass (spin)." in text
    assert text.startswith(GENERATED.format(source="x.csv")) and text.endswith(END + "\n")


@pytest.mark.parametrize(
    ("passed", "judged", "word"),
    [(2, 2, "met"), (2, 3, "met"), (1, 3, "not met"), (0, 2, "not met"), (1, 2, "undecided"),
     (0, 1, "undecided"), (0, 0, "undecided")],
)  # fmt: skip
def test_the_goal_is_decided_once_two_of_three_pass_or_no_longer_can(passed, judged, word):
    from experiments.suites.verdict import goal

    assert goal(passed, judged) == word


def test_r_below_20_says_nothing_about_the_return_at_its_budget():
    rows = [
        *_rows("spin", "r", [5, 6, 7], [10, 12, 14]),
        *_rows("spin", "r+rf+rsp", [0] * 3, [1] * 3),
    ]
    assert "| not judged: r does not learn at 50k; gentler |" in verdict_markdown(rows, "x.csv")


@pytest.mark.parametrize(
    ("path", "source", "block"),
    committed_blocks(GENERATED, END),
)
def test_each_committed_verdict_is_what_its_csv_gives(path, source, block, monkeypatch):
    from gentlerl.analysis.results import read_results

    monkeypatch.chdir(ROOT)
    assert verdict_markdown(read_results(Path(source)), source) == block, f"{path}: rerun it"
