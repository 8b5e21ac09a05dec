"""Collection in a child process, one batch ahead of the learner: both cores busy.

:class:`ProcessCollector` has :class:`~gentlerl.training.prefetch.PrefetchCollector`'s semantics
with the collector in a child process, so the hands' physics and the actor's forward pass run on
another core than the learner, with no GIL between them. The child owns a TorchRL ``Collector``
built around a copy of the policy (:func:`~gentlerl.training.prefetch.snapshot_policy`: the
exploration noise draws from its own seeded generator). Each "next batch" request carries the
learner's actor weights, which the child loads before it collects: batch ``k + 1`` is requested
as batch ``k`` arrives, with the weights the learner had after training on batch ``k - 1`` (one
batch of policy lag, whatever the timing). Batches come back in order, time-contiguous per env
row; the child's global torch generator (random actions of ``init_random_frames``) is seeded
with the envs. Same seed, same run; past ``init_random_frames`` the same batches as the thread
(whose random actions draw from the learner process's generator instead).

TorchRL's ``AsyncCollector`` (one worker process) was not used: it puts a CPU policy's weights
in shared memory that its worker reads while it collects, and its iterator refreshes them only
from the policy it was given, so the learner's weights would have to be written into that
memory while the worker runs (a batch could mix two versions); the seeded noise module did not
reach its worker either (its tensors travel through shared memory file descriptors). Messages
here are plain pickles over a pipe: the weights and a 200-frame batch are a few hundred kB.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import pickle
import signal
import sys
import traceback
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from typing import Any

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.collectors import Collector

from gentlerl.training.prefetch import snapshot_policy

#: Seconds the child gets to close its envs before it is terminated.
SHUTDOWN_TIMEOUT_S = 30.0


def _send(conn: Connection, message: Any) -> None:
    conn.send_bytes(pickle.dumps(message))


def _receive(conn: Connection) -> Any:
    return pickle.loads(conn.recv_bytes())


#: Linux's ``prctl`` option: the signal the kernel sends a process when its parent ends.
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int) -> None:
    """End this child with its parent, however the parent ends (a SIGKILL, a SIGTERM caught
    during the child's start): on Linux the kernel sends it SIGKILL (``PR_SET_PDEATHSIG``);
    a parent gone before that was set ends it here. Elsewhere the closed pipe ends it."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:
        os._exit(1)


def _serve(conn: Connection, setup: bytes, parent: int) -> None:
    """The child: build the collector, then answer ``seed`` / ``next`` / ``close`` requests
    with ``("ok", result)`` or ``("error", traceback)``; it never outlives ``parent``."""
    _die_with_parent(parent)
    torch.set_num_threads(1)
    try:
        make_collector, policy = pickle.loads(setup)
        collector = make_collector(policy)
        batches: Iterator[TensorDictBase] | None = None
        _send(conn, ("ok", None))
    except BaseException:
        _send(conn, ("error", traceback.format_exc()))
        return
    while True:
        command, arg = _receive(conn)
        try:
            if command == "seed":
                torch.manual_seed(arg)
                policy[1].generator.manual_seed(arg)
                result = collector.set_seed(arg)
            elif command == "next":
                policy[0].load_state_dict(arg)
                batches = batches if batches is not None else iter(collector)
                result = next(batches, None)
            else:
                collector.shutdown()
                _send(conn, ("ok", None))
                return
            _send(conn, ("ok", result))
        except BaseException:
            _send(conn, ("error", traceback.format_exc()))


class CollectorDied(ChildProcessError):
    """The collector's child process ended without being asked to (killed, out of memory)."""


def _ended(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        return f"the collector process was killed by {signal.Signals(-exitcode).name}"
    return f"the collector process ended unexpectedly (exit code {exitcode})"


class ProcessCollector:
    """A TorchRL ``Collector`` in a child process, one batch ahead; see the module doc.

    Args:
        make_collector: builds the ``Collector`` from the policy it is given (pickled to the
            child: a module-level function or a ``functools.partial`` of one).
        policy: ``(actor, AdditiveGaussianModule)``, the actor being the learner's (trained in
            place): the child gets a copy with seeded noise.
        seed: of the exploration noise (:meth:`set_seed` re-seeds it with the envs).
    """

    def __init__(
        self,
        make_collector: Callable[[TensorDictModule], Collector],
        policy: TensorDictSequential,
        seed: int = 0,
    ) -> None:
        self._actor = policy[0]
        snapshot = snapshot_policy(policy)
        snapshot[1].generator.manual_seed(seed)
        try:
            setup = pickle.dumps((make_collector, snapshot))
        except (pickle.PicklingError, TypeError, AttributeError) as err:
            raise ValueError(
                "collector.overlap=process sends the env factory to a child process, so it must "
                f"be picklable (a module-level function or a partial of one): {err}"
            ) from err
        context = multiprocessing.get_context("spawn")
        self._conn, child_conn = context.Pipe()
        self._process = context.Process(
            target=_serve, args=(child_conn, setup, os.getpid()), name="collector", daemon=True
        )
        self._process.start()
        child_conn.close()
        self._open = 1  # the child's "built" (or its error)
        try:
            self._answer()
        except BaseException:
            self.shutdown()
            raise

    def _answer(self) -> Any:
        """The child's answer to the oldest open request; its error raised here."""
        try:
            status, result = _receive(self._conn)
        except (EOFError, OSError) as err:  # a closed pipe, or reset while it was writing
            raise self._died() from err
        finally:
            self._open -= 1
        if status == "error":
            raise RuntimeError(f"the collector process failed:\n{result}")
        return result

    def _died(self) -> CollectorDied:
        """The error for a child that ended unasked, once it is reaped (its exit code known)."""
        self._process.join(SHUTDOWN_TIMEOUT_S)
        return CollectorDied(_ended(self._process.exitcode))

    def _request(self, command: str, arg: Any = None) -> None:
        try:
            _send(self._conn, (command, arg))
        except OSError as err:  # BrokenPipeError / ConnectionResetError: the child is gone
            raise self._died() from err
        self._open += 1

    def set_seed(self, seed: int) -> int:
        """Seed the envs (TorchRL), the exploration noise and the child's torch generator."""
        self._request("seed", seed)
        return self._answer()

    def _request_batch(self) -> None:
        """Ask for the next batch, collected with the learner's actor as it is now."""
        weights = {k: v.detach() for k, v in self._actor.state_dict().items()}
        self._request("next", weights)  # pickled now: the learner's later steps do not reach it

    def __iter__(self) -> Iterator[TensorDictBase]:
        self._request_batch()
        while True:
            batch = self._answer()
            if batch is None:
                return
            # Batch k is in: batch k + 1 gets the weights after training on batch k - 1.
            self._request_batch()
            yield batch

    def shutdown(self) -> None:
        """Close the child's envs and end it (terminated after :data:`SHUTDOWN_TIMEOUT_S`)."""
        if self._conn.closed:
            return
        try:
            self._request("close")
            while self._open and self._conn.poll(SHUTDOWN_TIMEOUT_S):
                self._open -= 1
                _receive(self._conn)  # a batch asked for and not taken, then the close
        except (OSError, EOFError):
            pass
        self._process.join(SHUTDOWN_TIMEOUT_S)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._conn.close()
