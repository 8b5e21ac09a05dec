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


@pytest.mark.parametrize(
    ("ci_slow", "pytest_exit", "ci_exit"), [("1", 0, 0), ("1", 5, 5), ("0", 0, 0)]
)
def test_ci_slow_runs_the_slow_tests_after_the_suite_and_fails_on_exit_5(
    tmp_path, ci_slow, pytest_exit, ci_exit
):
    # The script from run_suite to the CI_SLOW block, with a `python` that records its arguments
    # and exits 0 for the normal suite and `pytest_exit` for `-m slow`.
    text = CI.read_text()
    start = text.index("run_suite() {")
    end = text.index("\nfi\n", text.index('if [ "${CI_SLOW:-0}" = "1" ]')) + 4
    log = tmp_path / "calls"
    (tmp_path / "python").write_text(
        f'#!/bin/sh\necho "$*" >> {log}\n'
        f'case "$*" in *"-m slow"*) exit {pytest_exit};; esac\nexit 0\n'
    )
    (tmp_path / "python").chmod(0o755)
    script = f"set -euo pipefail\n{text[start:end]}\necho after the slow tests\n"
    done = subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, timeout=30,
        env={"PATH": f"{tmp_path}:/usr/bin:/bin", "CI_SLOW": ci_slow},
    )  # fmt: skip
    calls = [c for c in log.read_text().splitlines() if c.startswith("-m pytest")]
    assert done.returncode == ci_exit, done.stderr
    assert ("after the slow tests" in done.stdout) == (ci_exit == 0)
    normal = [c for c in calls if "-m slow" not in c]
    slow = [c for c in calls if "-m slow" in c]
    assert len(normal) == 2 and all(c == "-m pytest -q -p no:cacheprovider" for c in normal)
    assert slow == (["-m pytest -q -p no:cacheprovider -m slow"] if ci_slow == "1" else [])
    assert calls[-1] == (slow[0] if slow else normal[-1])  # after the normal suite


@pytest.mark.parametrize(("apt_exit", "said"), [(0, "libosmesa6 installed"), (100, "could not")])
def test_a_host_without_osmesa_gets_it_between_the_two_passes(tmp_path, apt_exit, said):
    """The rendering tests' two halves: the first pass runs without OSMesa; .ci/run installs
    it (root, apt-get) before the second pass; a failed install skips that half, CI goes on."""
    text = CI.read_text()
    start = text.index("run_suite() {")
    end = text.index("\nrun_suite env ATEN_CPU_CAPABILITY=default") + 1
    log = tmp_path / "calls"
    fakes = {
        "python": f'echo "python $*" >> {log}\ncase "$*" in *find_library*) exit 1;; esac\nexit 0',
        "apt-get": f'echo "apt-get $*" >> {log}\nexit {apt_exit}',
        "id": "echo 0",
    }
    for name, body in fakes.items():
        (tmp_path / name).write_text(f"#!/bin/sh\n{body}\n")
        (tmp_path / name).chmod(0o755)
    script = f"set -euo pipefail\n{text[start:end]}run_suite env\necho second pass\n"
    done = subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, timeout=30,
        env={"PATH": f"{tmp_path}:/usr/bin:/bin"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    calls = log.read_text().splitlines()
    install = [i for i, c in enumerate(calls) if c.startswith("apt-get install")]
    suites = [i for i, c in enumerate(calls) if c.startswith("python -m pytest")]
    assert len(install) == 1 and "libosmesa6" in calls[install[0]]
    assert suites[0] < install[0]  # the first pass ran before, without OSMesa
    assert said in done.stdout and "second pass" in done.stdout
