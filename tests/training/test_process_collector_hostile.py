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


_PARENT = """
import sys
from pathlib import Path
from gentlerl.training.loop import train
from tests.training.test_process_collector_hostile import _process_run, stalling_env
train(_process_run(Path(sys.argv[1]))[0], stalling_env)
"""


def stalling_env():
    """The toy env, whose steps take a minute each once the file ``$STALL_FLAG`` exists: a
    collector busy in the physics when its run is killed (it reads no pipe until it is done)."""
    import time

    from tests.helpers import toy_env

    env = toy_env()
    step = env._step

    def slow_step(tensordict):
        if os.path.exists(os.environ["STALL_FLAG"]):
            time.sleep(60)
        return step(tensordict)

    env._step = slow_step
    return env


def _children(pid: int) -> list[int]:
    """The live processes whose parent is ``pid`` (Linux's /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if entry.name.isdigit() and int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc")
def test_the_collector_process_never_outlives_a_killed_run(tmp_path):
    """The finding: a run stopped under load left its collector child running (1 of 2 tries).
    Killed with SIGKILL (no handler, no cleanup) while its collector is in a long env step (it
    would see the closed pipe only a minute later), the collector ends with it."""
    import signal
    import subprocess
    import sys
    import time

    root = Path(__file__).resolve().parents[2]
    flag = tmp_path / "stall"
    path = os.pathsep.join([str(root / "src"), str(root)])
    env = {**os.environ, "PYTHONPATH": path, "STALL_FLAG": str(flag)}
    run = subprocess.Popen([sys.executable, "-c", _PARENT, str(tmp_path)], cwd=root, env=env)
    try:
        for _ in range(1200):  # the collector is serving batches once a checkpoint is written
            if (tmp_path / "checkpoint.pt").exists() or run.poll() is not None:
                break
            time.sleep(0.05)
        assert run.poll() is None, "the run ended before its first checkpoint"
        children = _children(run.pid)
        assert children, "no collector process found"
        flag.touch()
        time.sleep(1.0)  # the collector is now in a minute-long step
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        for _ in range(200):
            if not any(_alive(child) for child in children):
                break
            time.sleep(0.05)
        assert not any(_alive(child) for child in children)
    finally:
        if run.poll() is None:
            run.kill()
