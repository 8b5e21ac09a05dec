"""An interrupted local grid leaves no trainer behind: Ctrl-C kills each trainer's process group."""

from __future__ import annotations

import os
import threading

import pytest

SPAWNING_RECIPE = """
import subprocess, sys, time
from pathlib import Path
run_dir = Path(next(a for a in sys.argv if a.startswith("run_dir="))[8:])
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
(run_dir / "pids").write_text(f"{child.pid}\\n")
time.sleep(120)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie is dead too
        return f.read().split(")")[-1].split()[0] != "Z"


def test_an_interrupted_sweep_kills_its_trainers_process_groups(tmp_path):
    import dataclasses
    import signal
    import time

    from gentlerl.apps.grid import expand, run_grid

    script = tmp_path / "spawning.py"
    script.write_text(SPAWNING_RECIPE)
    grid = expand({"seed": [0, 1]}, tmp_path / "g")
    runs = [dataclasses.replace(r, script=script) for r in grid]
    pids = runs[0].run_dir / "pids"

    def ctrl_c_once_the_trainer_runs() -> None:
        for _ in range(400):
            if pids.exists() and pids.read_text().endswith("\n"):
                break
            time.sleep(0.05)
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C: KeyboardInterrupt in the main thread

    # Ctrl-C raises KeyboardInterrupt even where pytest inherited SIGINT ignored (a shell starts
    # background jobs so, and Python then keeps it ignored).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        threading.Thread(target=ctrl_c_once_the_trainer_runs, daemon=True).start()
        with pytest.raises(KeyboardInterrupt):
            run_grid(runs, workers=1)
    finally:
        signal.signal(signal.SIGINT, previous)
    grandchild = int(pids.read_text())
    for _ in range(100):
        if not _alive(grandchild):
            break
        time.sleep(0.05)
    assert not _alive(grandchild)  # the trainer's own child too: its whole group
    assert not (runs[1].run_dir / "stdout.log").exists()  # the queued point never started
