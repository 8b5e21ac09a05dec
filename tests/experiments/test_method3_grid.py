"""experiments/method3/grid.sh: which sweep files it runs, and a --kinds typo refused before any."""

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess, list[str]]:
    """The script with stubs of ``gentlerl`` and ``python`` that record each call's arguments."""
    stub = tmp_path / "bin"
    stub.mkdir(parents=True, exist_ok=True)
    for name, prefix in (("gentlerl", ""), ("python", "python ")):
        (stub / name).write_text(f'#!/bin/sh\necho "{prefix}$*" >> "$CALLS"\n')
        (stub / name).chmod(0o755)
    calls = tmp_path / "calls"
    env = {**os.environ, "PATH": f"{stub}:{os.environ['PATH']}", "CALLS": str(calls)}
    proc = subprocess.run(
        ["bash", str(ROOT / "experiments" / "method3" / "grid.sh"), "--out", str(tmp_path), *args],
        env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    return proc, calls.read_text().splitlines() if calls.exists() else []


def test_a_kind_a_task_lacks_is_skipped_and_one_no_task_has_is_refused(tmp_path):
    tasks = ["--tasks", "finger_turn_easy,touch", "--kinds", "_deployed,_pidonly"]
    proc, calls = _run(tmp_path, *tasks)
    assert proc.returncode == 0, proc.stderr
    sweeps = [c.split()[1].rsplit("/", 1)[-1] for c in calls if c.startswith("sweep ")]
    assert sweeps == [
        "method3_finger_turn_easy_deployed.yaml",
        "method3_touch_deployed.yaml",
        "method3_touch_pidonly.yaml",
    ]
    assert "finger_turn_easy has no '_pidonly' runs, skipped" in proc.stderr
    assert calls[-1] == f"python experiments/method3/table.py {tmp_path}"
    proc, calls = _run(tmp_path / "typo", "--tasks", "touch", "--kinds", "_deploy")
    assert proc.returncode == 2 and calls == []
    assert "--kinds '_deploy' names no sweep file of the tasks touch" in proc.stderr


def test_finger_spin_runs_at_its_own_budget(tmp_path):
    """50k env steps on finger-spin (where `r` learns it), 30k everywhere else; one each."""
    proc, calls = _run(
        tmp_path, "--tasks", "finger_spin,finger_turn_easy", "--kinds", "_deployedw1"
    )
    assert proc.returncode == 0, proc.stderr
    sweeps = [c for c in calls if c.startswith("sweep ")]
    assert [c.split()[1].rsplit("/", 1)[-1] for c in sweeps] == [
        "method3_finger_spin_deployedw1.yaml",
        "method3_finger_turn_easy_deployedw1.yaml",
    ]
    frames = [[a for a in c.split() if a.startswith("collector.total_frames=")] for c in sweeps]
    assert frames == [["collector.total_frames=50000"], ["collector.total_frames=30000"]]


def test_frames_sets_every_tasks_budget_and_a_bad_one_is_refused(tmp_path):
    """--frames N replaces each task's budget (the sixth amendment's finger-turn_easy probe)."""
    proc, calls = _run(
        tmp_path, "--tasks", "finger_turn_easy", "--kinds", "_budget", "--frames", "100000"
    )
    assert proc.returncode == 0, proc.stderr
    sweeps = [c for c in calls if c.startswith("sweep ")]
    assert [c.split()[1].rsplit("/", 1)[-1] for c in sweeps] == [
        "method3_finger_turn_easy_budget.yaml"
    ]
    assert "collector.total_frames=100000" in sweeps[0].split()
    for bad in ("0", "1e5", "-5", "10k"):
        proc, calls = _run(tmp_path / f"bad{bad}", "--frames", bad)
        assert proc.returncode == 2 and calls == [], bad
        assert f"--frames must be a positive integer, got '{bad}'" in proc.stderr
