"""RunLock: one writer per run directory; a dead holder's lock is taken over."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def test_a_run_directory_has_one_writer(tmp_path):
    from gentlerl.training.run_lock import RunLock, RunLockedError

    run_dir = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_LOCK, str(run_dir)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunLockedError, match=f"in use by pid {holder.pid} on ") as err:
            RunLock(run_dir).acquire()
        assert "\n" not in str(err.value)
    finally:
        holder.kill()
        holder.wait()
    # The holder was killed: its lock is stale and taken over.
    assert (run_dir / ".lock").read_text().startswith(f"pid {holder.pid}")
    with RunLock(run_dir):
        assert (run_dir / ".lock").read_text().startswith(f"pid {os.getpid()}")
    assert not run_dir.exists() or not (run_dir / ".lock").exists()


HOLD_LOCK = """
import sys, time
from gentlerl.training.run_lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("locked", flush=True)
time.sleep(60)
"""
