"""``.ci/run`` fails when pytest collects nothing (exit 5: a marker or path mistake), as it does
on a failing test, and passes only on exit 0."""

import subprocess
from pathlib import Path

import pytest

CI = Path(__file__).resolve().parents[2] / ".ci" / "run"


@pytest.mark.parametrize(("pytest_exit", "ci_exit"), [(0, 0), (1, 1), (5, 5)])
def test_the_suite_step_fails_unless_pytest_passes(tmp_path, pytest_exit, ci_exit):
    # .ci/run's own run_suite, with a `python` that exits as pytest would, under the script's
    # `set -euo pipefail`: the line after it runs only if the suite passed.
    text = CI.read_text()
    start = text.index("run_suite() {")
    function = text[start : text.index("\n}\n", start) + 3]
    (tmp_path / "python").write_text(f"#!/bin/sh\nexit {pytest_exit}\n")
    (tmp_path / "python").chmod(0o755)
    script = f"set -euo pipefail\n{function}\nrun_suite env\necho after the suite\n"
    done = subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, timeout=30,
        env={"PATH": f"{tmp_path}:/usr/bin:/bin"},
    )  # fmt: skip
    assert done.returncode == ci_exit
    assert ("after the suite" in done.stdout) == (ci_exit == 0)
    assert ("collected no tests (exit 5)" in done.stdout) == (pytest_exit == 5)
    assert "\nrun_suite env\n" in text and "\nrun_suite env ATEN_CPU_CAPABILITY=default" in text
