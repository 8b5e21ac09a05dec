"""The hand *driver* protocol: what :class:`~gentlerl.envs.DriverHandEnv` needs from a hand.

A driver is any object with a :class:`DriverSpec` ``spec`` attribute and four methods::

    reset() -> np.ndarray          # go to the start pose; return the commanded targets [20]
    read() -> HandReading          # latest joints, raw tactile, block force, actuator forces
    command(targets) -> None       # send position targets [20]; return at the next 20 Hz tick
    close() -> None                # release the hardware

The driver owns the clock: ``command`` returns once the targets have been applied for one control
period (50 ms; a real driver sleeps to the next tick, the simulated one steps MuJoCo 25 x 2 ms),
so the env's step is the paper's 20 Hz control step. Tactile readings are *raw* (sensor units,
e.g. BioTac pressure counts); the env maps them to newtons with a
:class:`~gentlerl.transforms.TouchSensorMap`. A real hand's driver wraps its own interface (ROS
topics, a vendor SDK) behind these four methods.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from gentlerl.envs.assets import CHANNELS, TOUCH_SITES
from gentlerl.envs.hand import N_ACTUATORS, N_JOINTS
from gentlerl.envs.watchdog import NEGATIVE_TOLERANCE

N_SITES = len(TOUCH_SITES)


@dataclass(frozen=True)
class DriverSpec:
    """What a driver reads and accepts.

    Attributes:
        target_low, target_high: ``[20]`` position-target limits (rad) of the actuators, in the
            MJCF's actuator order; actions are scaled by ``high - low`` and clipped to them.
        tactile_channels: raw tactile channels per fingertip (1 for a BioTac's pressure channel;
            at most 3, the simulated touch channels they stand for: normal, then tangential).
        has_block_force: whether :class:`HandReading` carries ``block_force`` (a force/torque
            sensor under the block, as in the paper's real-robot setup).
        has_actuator_force: whether :class:`HandReading` carries ``actuator_force`` (the
            actuators' efforts, e.g. ``effort`` of a ROS ``JointState``); without it the env
            writes zeros there, so effort-based rewards (``TorquePenalty``) need it.
    """

    target_low: np.ndarray
    target_high: np.ndarray
    tactile_channels: int = 1
    has_block_force: bool = False
    has_actuator_force: bool = False

    def __post_init__(self) -> None:
        for name in ("target_low", "target_high"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != (N_ACTUATORS,) or not np.isfinite(value).all():
                raise ValueError(
                    f"DriverSpec.{name} must be {N_ACTUATORS} finite values, got {value!r}"
                )
            object.__setattr__(self, name, value)
        if not (self.target_low < self.target_high).all():
            raise ValueError(
                f"DriverSpec: target_low must be < target_high per actuator, got "
                f"{self.target_low} and {self.target_high}"
            )
        if not 1 <= self.tactile_channels <= CHANNELS:
            raise ValueError(
                f"DriverSpec.tactile_channels must be in [1, {CHANNELS}], "
                f"got {self.tactile_channels!r}"
            )


@dataclass
class HandReading:
    """One :meth:`HandDriver.read`: ``joint_pos`` / ``joint_vel`` ``[24]`` (rad, rad/s),
    in the MJCF's joint order (WRJ1, WRJ0, FFJ3, ..., THJ0),
    ``tactile`` ``[5, tactile_channels]`` raw sensor values per fingertip (ff, mf, rf, lf, th),
    ``block_force`` (N) or ``None`` without a block sensor, ``actuator_force`` ``[20]`` (N m) or
    ``None`` where the driver does not report efforts."""

    joint_pos: np.ndarray
    joint_vel: np.ndarray
    tactile: np.ndarray
    block_force: float | None = None
    actuator_force: np.ndarray | None = None


@runtime_checkable
class HandDriver(Protocol):
    """The driver protocol (see the module docstring)."""

    spec: DriverSpec

    def reset(self) -> np.ndarray: ...

    def read(self) -> HandReading: ...

    def command(self, targets: np.ndarray) -> None: ...

    def close(self) -> None: ...


def _checked(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"driver reading {name!r} has shape {array.shape}, expected {shape}")
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise ValueError(
            f"driver reading {name!r} has non-finite values at flat indices {bad.tolist()}: "
            f"{array.reshape(-1)[bad].tolist()}"
        )
    return array


def check_reading(reading: HandReading, spec: DriverSpec) -> HandReading:
    """``reading`` as float64 arrays, or a ``ValueError`` naming the wrong-shaped / non-finite
    field (a driver bug or a sensor fault must not reach the learner as NaN)."""
    block = reading.block_force
    if spec.has_block_force:
        if block is None:
            raise ValueError("driver reading 'block_force' is None but spec.has_block_force=True")
        block = float(_checked("block_force", block, ()))
        if block < -NEGATIVE_TOLERANCE:
            raise ValueError(
                f"driver reading 'block_force'={block} N is implausible (a force sensor reads "
                f">= -{NEGATIVE_TOLERANCE} N): a sensor fault or a sign error in the driver"
            )
    elif block is not None:
        raise ValueError("driver reading 'block_force' is set but spec.has_block_force=False")
    effort = reading.actuator_force
    if spec.has_actuator_force != (effort is not None):
        raise ValueError(
            f"driver reading 'actuator_force' is {'None' if effort is None else 'set'} but "
            f"spec.has_actuator_force={spec.has_actuator_force}"
        )
    return HandReading(
        joint_pos=_checked("joint_pos", reading.joint_pos, (N_JOINTS,)),
        joint_vel=_checked("joint_vel", reading.joint_vel, (N_JOINTS,)),
        tactile=_checked("tactile", reading.tactile, (N_SITES, spec.tactile_channels)),
        block_force=block,
        actuator_force=None
        if effort is None
        else _checked("actuator_force", effort, (N_ACTUATORS,)),
    )


def check_targets(targets: object, spec: DriverSpec, source: str) -> np.ndarray:
    """``[20]`` finite targets inside the spec's limits, or a ``ValueError`` naming ``source``."""
    array = _checked(source, targets, (N_ACTUATORS,))
    outside = np.flatnonzero((array < spec.target_low) | (array > spec.target_high))
    if outside.size:
        raise ValueError(
            f"{source} targets {array[outside].tolist()} (actuators {outside.tolist()}) are "
            f"outside [target_low, target_high]"
        )
    return array


class DriverTimeout(TimeoutError):
    """``driver.read()`` gave no reading within the read timeout."""


class TimedRead:
    """``driver.read()`` on a daemon thread, waited for at most ``timeout`` s (``None``: no limit).

    A stalled read raises :class:`DriverTimeout` instead of blocking the control loop; while it
    is still stalled, the next call waits for it (one read at a time) and raises again if it
    does not finish within ``timeout``.
    """

    def __init__(self, read: Callable[[], HandReading], timeout: float | None) -> None:
        if timeout is not None and not (
            isinstance(timeout, int | float) and math.isfinite(timeout) and timeout > 0
        ):
            raise ValueError(f"read_timeout must be a positive number of seconds, got {timeout!r}")
        self.read, self.timeout = read, timeout
        self._thread: threading.Thread | None = None

    def __call__(self) -> HandReading:
        if self.timeout is None:
            return self.read()
        if self._thread is not None and self._thread.is_alive():
            self._thread.join(self.timeout)
            if self._thread.is_alive():
                raise DriverTimeout(f"driver.read() is still stalled after {self.timeout} s more")
        box: dict[str, object] = {}

        def run() -> None:
            try:
                box["reading"] = self.read()
            except BaseException as err:  # noqa: BLE001 - re-raised on the caller's thread
                box["error"] = err

        self._thread = threading.Thread(target=run, name="driver-read", daemon=True)
        self._thread.start()
        self._thread.join(self.timeout)
        if self._thread.is_alive():
            raise DriverTimeout(f"driver.read() gave no reading within {self.timeout} s")
        if "error" in box:
            raise box["error"]  # type: ignore[misc]
        return box["reading"]  # type: ignore[return-value]
