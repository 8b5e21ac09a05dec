"""A process-collector run stopped by SIGTERM or by its collector's death ends cleanly and says how to
resume."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest


def _process_run(tmp_path: Path):
    from gentlerl.training.config import make_config
    from tests.helpers import TINY, toy_env

    fast = {**TINY["collector"], "overlap": "process", "total_frames": 10**6}
    logging = {**TINY["logging"], "checkpoint_every_frames": 100, "eval_every_frames": 10**6}
    cfg = make_config(**{**TINY, "collector": fast, "logging": logging, "run_dir": str(tmp_path)})
    return cfg, toy_env


def _when_checkpointed(run_dir: Path, then) -> threading.Thread:
    """A thread calling ``then()`` once ``run_dir`` holds a checkpoint (at most 60 s on)."""
    import time

    def wait() -> None:
        for _ in range(1200):
            if (run_dir / "checkpoint.pt").exists():
                break
            time.sleep(0.05)
        then()

    thread = threading.Thread(target=wait, daemon=True)
    thread.start()
    return thread


def test_sigterm_stops_a_process_collector_run_as_ctrl_c_does(tmp_path):
    import multiprocessing
    import signal

    from gentlerl.apps.errors import Terminated, exit_status, sigterm_as_interrupt
    from gentlerl.training.checkpoint import load_checkpoint
    from gentlerl.training.loop import train

    cfg, env = _process_run(tmp_path)
    _when_checkpointed(tmp_path, lambda: os.kill(os.getpid(), signal.SIGTERM))
    with pytest.raises(Terminated) as err, sigterm_as_interrupt():
        train(cfg, env)
    assert exit_status(err.value) == 143 and not multiprocessing.active_children()
    assert not (tmp_path / ".lock").exists()  # the lock released
    assert int(load_checkpoint(tmp_path / "checkpoint.pt")["counters"]["frames"]) >= 100


def test_a_killed_collector_process_says_what_happened_and_that_resume_continues(tmp_path):
    import multiprocessing
    import signal

    from gentlerl.apps.errors import one_line
    from gentlerl.training.loop import train

    def kill_collector() -> None:
        for child in multiprocessing.active_children():
            if child.name == "collector":
                os.kill(child.pid, signal.SIGKILL)

    cfg, env = _process_run(tmp_path)
    _when_checkpointed(tmp_path, kill_collector)
    with pytest.raises(ChildProcessError) as err:
        train(cfg, env)
    message = one_line(err.value)
    assert message.startswith("the collector process was killed by SIGKILL; the last checkpoint")
    assert message.endswith("is intact: rerun with resume=auto to continue")
    assert not (tmp_path / ".lock").exists() and not multiprocessing.active_children()
