"""The suite fails loudly instead of hanging: a test blocked in C is stopped with its stack."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_a_test_blocked_in_c_is_stopped_with_its_stack_and_a_failing_exit(tmp_path):
    # ``Lock.acquire`` with no timeout blocks in C; pyproject's ``timeout_method = "thread"`` must
    # still dump the stack and end the process with a non-zero code.
    (tmp_path / "test_blocked.py").write_text(
        "import threading\n\ndef test_blocks():\n    lock = threading.Lock()\n"
        "    lock.acquire()\n    lock.acquire()\n"
    )
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-o", "timeout=2",
         "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(tmp_path), str(tmp_path)],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode not in (0, 5), out.stdout
    assert "Timeout" in out.stdout + out.stderr
    assert "test_blocked.py" in out.stdout + out.stderr  # the blocked frame is named
