"""One writer per run directory: ``run_dir/.lock``, held with ``flock`` for the life of a run.

Two ``gentlerl train ... resume=auto`` on one run directory would both append to its CSV files
and overwrite each other's checkpoints. The lock file names its holder (pid and host) so the
second one is refused in one line saying who holds it. ``flock`` is released by the kernel when
the holder dies, so a lock left by a killed run is stale and the next run takes it over.

A run writes only files it makes: a run directory that is itself a symbolic link, or a symbolic
link in the run directory (planted, say, as
``.lock`` or ``config.yaml`` pointing at a file elsewhere) is refused before anything is written.
"""

from __future__ import annotations

import fcntl
import os
import socket
from pathlib import Path

from gentlerl.config.layout import RunLayout
from gentlerl.files import LinkRefusedError, folder_link_problem, links_under

#: The run directories whose lock this process holds (resolved), so that a driver taking the
#: locks of its runs (:class:`~gentlerl.training.loop.Lockstep`) does not take one its
#: caller holds (``flock`` would refuse this process its own lock).
#: Each entry names its process: a forked child inherits the set, not the locks.
_HELD: set[tuple[int, Path]] = set()


def held_here(run_dir: str | os.PathLike) -> bool:
    """Whether this process holds the lock of ``run_dir``."""
    return (os.getpid(), Path(run_dir).resolve()) in _HELD


class RunLockedError(OSError):
    """The run directory is held by another live process (busy); the message names it."""


class RunLock:
    """Hold ``run_dir/.lock`` (``with RunLock(run_dir): ...``); creates ``run_dir`` (and on
    release removes the folders it created that are still empty, ``run_dir`` and its parents).

    Raises:
        RunLockedError: another live process holds it.
        LinkRefusedError: the run directory holds a symbolic link (nothing was written).
    """

    def __init__(self, run_dir: str | os.PathLike) -> None:
        self.path = RunLayout(run_dir).lock
        self._fd: int | None = None
        #: The folders this lock created, deepest first.
        self._made: list[Path] = []

    def acquire(self) -> RunLock:
        run_dir = self.path.parent
        if problem := folder_link_problem(run_dir):
            raise LinkRefusedError(problem)
        self._made = [d for d in (run_dir, *run_dir.parents) if not d.exists()]
        run_dir.mkdir(parents=True, exist_ok=True)
        self._refuse_links(run_dir)
        for _ in range(10):  # the file may be removed by its holder between open and flock
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
                os.close(fd)
                self._remove_empty_dir()
                raise RunLockedError(
                    f"run_dir={str(self.path.parent)!r} is in use by {holder} (lock {self.path}); "
                    "wait for that run to end or stop it, or choose another run_dir"
                ) from None
            if _same_file(fd, self.path):
                os.ftruncate(fd, 0)
                os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode())
                self._fd = fd
                _HELD.add((os.getpid(), run_dir.resolve()))
                return self
            os.close(fd)
        raise RunLockedError(f"could not take the lock {self.path}: it keeps changing")

    def _refuse_links(self, run_dir: Path) -> None:
        links = links_under(run_dir)
        if links:
            self._remove_empty_dir()
            shown = ", ".join(str(p) for p in links[:3]) + (" ..." if len(links) > 3 else "")
            raise LinkRefusedError(
                f"run_dir={str(run_dir)!r} holds {len(links)} symbolic link(s) ({shown}): a run "
                "writes only files it makes there; remove them or choose another run_dir"
            )

    def release(self) -> None:
        if self._fd is not None:
            _HELD.discard((os.getpid(), self.path.parent.resolve()))
            self.path.unlink(missing_ok=True)
            os.close(self._fd)
            self._fd = None
            self._remove_empty_dir()

    def _remove_empty_dir(self) -> None:
        """A run refused before writing anything leaves no empty folder it made behind."""
        for folder in self._made:
            if any(folder.iterdir()):
                return
            folder.rmdir()

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the file open at ``fd`` (not unlinked by its last holder)."""
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False
