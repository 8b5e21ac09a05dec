"""``DriverHandEnv``: the gentle-touch tasks as a TorchRL env over a hand driver (real or simulated).

Same observation keys and specs as :class:`~gentlerl.envs.HandEnv`, same action (a delta position
in [-1, 1]^20 at 20 Hz, scaled and clipped to the target limits by the task's own
``next_targets``) and the same task rules, reward and termination (the task objects of
:mod:`gentlerl.envs.hand` judge each step), so recipes and transforms run on it unchanged.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from gentlerl import keys
from gentlerl.envs.assets import CHANNELS, GRID
from gentlerl.envs.driver import (
    N_ACTUATORS,
    N_SITES,
    DriverTimeout,
    HandDriver,
    HandReading,
    TimedRead,
    check_reading,
    check_targets,
)
from gentlerl.envs.factory import TASK_CLASSES
from gentlerl.envs.hand import FLAT_SIZE, OBS_SIZE, OBS_SLICES, Explore
from gentlerl.envs.watchdog import ForceWatchdog

if TYPE_CHECKING:  # envs/ sits left of transforms/: the sensor map is only duck-typed here
    from gentlerl.transforms.sensor_map import TouchSensorMap

# A fingertip counts as on the block when it senses more than this while the block sensor does.
CONTACT_FORCE = 0.05


def _flag() -> Categorical:
    return Categorical(2, (1,), dtype=torch.bool)


class DriverHandEnv(EnvBase):
    """A gentle-touch task on a :class:`~gentlerl.envs.driver.HandDriver`.

    Each step: targets <- ``task.next_targets(targets, action)``; ``driver.command(targets)``
    (one 50 ms period); ``driver.read()`` (checked: shapes, finiteness); the raw tactile channels
    are mapped to newtons (after subtracting the baseline drift measured at reset, ``tare``)
    and padded with zeros to the 3 simulated channels; the task judges success / broken exactly
    as in simulation. Without contact geometry, a fingertip is on the block when it senses
    > 0.05 N while the block sensor does (every sensing fingertip counts without a block sensor).
    ``touch_grid`` spreads each fingertip's force evenly over its 4x4 taxels (a BioTac has no grid);
    ``actuator_force`` is the driver's, or zeros if it reports none (``spec.has_actuator_force``).

    Writes the keys of :class:`HandEnv` plus raw ``tactile`` ``[5, R]``, ``block_force`` ``[1]``
    (0 without a block sensor) and ``watchdog`` ``[1]`` (a :class:`ForceWatchdog` trip ended the
    episode: terminated, last safe targets held).

    Args:
        driver: the hand.
        task: ``"explore"``, ``"touch"``, ``"fragile"`` or a task object (:mod:`gentlerl.envs.hand`).
        sensor_map: a fitted :class:`TouchSensorMap` for the driver's tactile channels.
        watchdog: optional :class:`ForceWatchdog`.
        time_limit: control steps before truncation (200 = 10 s, as in simulation).
        tare: subtract each channel's reading at reset (hand open, nothing touched) from the
            sensor map's zero level, cancelling sensor drift since the fit.
        close_driver: :meth:`close` also closes the driver (False when envs share one driver).
        read_timeout: seconds a ``driver.read()`` may take (``None``: no limit). A step whose
            read stalls past it ends the episode as a watchdog trip does (terminated, the last
            targets re-commanded and held, ``watchdog=True``), warns, and counts in
            ``read_timeouts``; a reset whose read stalls raises :class:`DriverTimeout`.
        **task_kwargs: the task's arguments (``force_threshold``, ``break_impact``,
            ``action_scale``); with a task object, none.
    """

    def __init__(
        self,
        driver: HandDriver,
        task: str | Explore = "touch",
        *,
        sensor_map: TouchSensorMap,
        watchdog: ForceWatchdog | None = None,
        time_limit: int = 200,
        tare: bool = True,
        close_driver: bool = True,
        read_timeout: float | None = 1.0,
        **task_kwargs: Any,
    ) -> None:
        super().__init__(device="cpu", batch_size=torch.Size([]))
        self.task = _make_task(task, task_kwargs)
        self.driver, self.driver_spec = driver, driver.spec
        if sensor_map.shape != (N_SITES, self.driver_spec.tactile_channels):
            raise ValueError(
                f"sensor_map is for {sensor_map.shape} sites x channels; the driver reads "
                f"{(N_SITES, self.driver_spec.tactile_channels)}"
            )
        if not bool(sensor_map.fitted):
            raise ValueError("sensor_map is not fitted: call fit(raw, force) or load it first")
        sensor_map.validate()  # a NaN or flat map would blind the watchdog
        if watchdog is not None and watchdog.block_limit and not self.driver_spec.has_block_force:
            raise ValueError("watchdog.block_limit is set but the driver has no block sensor")
        if not (isinstance(time_limit, int | np.integer) and time_limit >= 1):
            raise ValueError(
                f"time_limit must be an integer >= 1 (control steps), got {time_limit!r}"
            )
        self.sensor_map, self.watchdog = sensor_map, watchdog
        self.read, self.read_timeouts = TimedRead(driver.read, read_timeout), 0
        self.time_limit, self.tare, self.close_driver = int(time_limit), tare, close_driver
        self.targets = np.zeros(len(self.driver_spec.target_low))
        self.offset: torch.Tensor | None = None
        self.touch = np.zeros((N_SITES, CHANNELS))
        self.steps = 0
        obs = _hand_env_specs()
        obs[keys.TACTILE] = Unbounded((N_SITES, self.driver_spec.tactile_channels))
        obs[keys.BLOCK_FORCE] = Unbounded((1,))
        obs[keys.WATCHDOG] = _flag()
        self.observation_spec = Composite(obs)
        self.action_spec = Bounded(-1.0, 1.0, (len(self.driver_spec.target_low),))
        self.reward_spec = Unbounded((1,))
        self.full_done_spec = Composite(done=_flag(), terminated=_flag(), truncated=_flag())

    # -- one reading ----------------------------------------------------------------------------
    def _sense(self) -> tuple[np.ndarray, HandReading]:
        """Read the driver; return the mapped ``touch`` [5, 3] (N) and the checked reading."""
        reading = check_reading(self.read(), self.driver_spec)
        force = self.sensor_map.forward_map(reading.tactile, self.offset).numpy()
        touch = np.zeros((N_SITES, CHANNELS))
        touch[:, : force.shape[-1]] = force
        return touch, reading

    def _output(
        self, touch: np.ndarray, reading: HandReading, flags: dict[str, bool]
    ) -> TensorDictBase:
        buf = np.empty(OBS_SIZE, dtype=np.float32)
        buf[: len(reading.joint_pos)] = reading.joint_pos
        buf[len(reading.joint_pos) : 2 * len(reading.joint_pos)] = reading.joint_vel
        buf[OBS_SLICES[keys.TOUCH][0]] = touch.reshape(-1)
        grid = np.repeat(touch.reshape(-1, 1) / (GRID[0] * GRID[1]), GRID[0] * GRID[1], axis=1)
        buf[OBS_SLICES[keys.TOUCH_GRID][0]] = grid.reshape(-1)
        effort = reading.actuator_force
        buf[OBS_SLICES[keys.ACTUATOR_FORCE][0]] = 0.0 if effort is None else effort
        t = torch.from_numpy(buf)
        out = {key: t[where].view(shape) for key, (where, shape) in OBS_SLICES.items()}
        out[keys.OBSERVATION] = t[:FLAT_SIZE].clone()
        out[keys.TACTILE] = torch.as_tensor(reading.tactile, dtype=torch.float32)
        out[keys.BLOCK_FORCE] = torch.tensor([reading.block_force or 0.0], dtype=torch.float32)
        flags = {keys.SUCCESS: self.task.success, keys.BROKEN: self.task.broken, **flags}
        out.update((key, torch.tensor([bool(v)])) for key, v in flags.items())
        return TensorDict(out, batch_size=[])

    # -- EnvBase --------------------------------------------------------------------------------
    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        self.targets = check_targets(self.driver.reset(), self.driver_spec, "driver.reset()")
        self.offset = None
        if self.tare:
            at_rest = check_reading(self.read(), self.driver_spec).tactile
            self.offset = self.sensor_map.tare(at_rest)
        touch, reading = self._sense()
        self.touch, self.reading, self.steps = touch, reading, 0
        self.task.success = self.task.broken = False
        return self._output(touch, reading, {keys.WATCHDOG: False})

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get(keys.ACTION).detach().cpu().numpy()
        low, high = self.driver_spec.target_low, self.driver_spec.target_high
        targets = self.task.next_targets(self.targets, action, low, high)
        self.driver.command(targets)
        try:
            touch, reading = self._sense()
        except DriverTimeout as err:
            return self._timed_out(err)
        block = reading.block_force
        tripped = self.watchdog is not None and self.watchdog.check(touch, block)
        if tripped:
            self.driver.command(self.targets)  # back to the last targets within the limits
        else:
            self.targets = targets
        sensing = touch[:, 0] > CONTACT_FORCE
        on_block = sensing & (block > CONTACT_FORCE) if block is not None else sensing
        self.task.update_outcome(touch, self.touch, on_block)
        self.touch, self.reading, self.steps = touch, reading, self.steps + 1
        terminated = tripped or self.task.get_termination(None) is not None
        truncated = not terminated and self.steps >= self.time_limit
        td = self._output(
            touch,
            reading,
            {
                keys.WATCHDOG: tripped,
                keys.TERMINATED: terminated,
                keys.TRUNCATED: truncated,
                keys.DONE: terminated or truncated,
            },
        )
        td.set(keys.REWARD, torch.tensor([self.task.get_reward(None)], dtype=torch.float32))
        return td

    def _timed_out(self, err: DriverTimeout) -> TensorDictBase:
        """End the episode safely after a stalled read: the last targets held, the last reading
        repeated, ``watchdog`` and ``terminated`` set, no reward."""
        self.driver.command(self.targets)
        self.read_timeouts += 1
        warnings.warn(f"{err}: episode ended, last targets held", RuntimeWarning, stacklevel=2)
        flags = dict.fromkeys((keys.WATCHDOG, keys.TERMINATED, keys.DONE), True)
        td = self._output(self.touch, self.reading, {**flags, keys.TRUNCATED: False})
        td.set(keys.REWARD, torch.zeros(1))
        return td

    def _set_seed(self, seed: int | None) -> None:
        reseed = getattr(self.driver, "seed", None)
        if callable(reseed) and seed is not None:
            reseed(seed)

    def close(self, *, raise_if_closed: bool = True) -> None:
        if getattr(self, "close_driver", False):  # False too if __init__ failed
            self.driver.close()
        super().close(raise_if_closed=raise_if_closed)


def _make_task(task: str | Explore, task_kwargs: dict[str, Any]) -> Explore:
    if isinstance(task, Explore):
        if task_kwargs:
            raise ValueError(f"task_kwargs {sorted(task_kwargs)} given with a task object")
        return task
    if task not in TASK_CLASSES:
        raise ValueError(f"unknown task {task!r}; expected one of {list(TASK_CLASSES)} or a task")
    return TASK_CLASSES[task](**task_kwargs)


def _hand_env_specs() -> dict[str, Any]:
    """:class:`~gentlerl.envs.HandEnv`'s observation specs (a test keeps the two equal)."""
    return {
        keys.JOINT_POS: Unbounded((24,)),
        keys.JOINT_VEL: Unbounded((24,)),
        keys.TOUCH: Unbounded((N_SITES, CHANNELS)),
        keys.TOUCH_GRID: Unbounded((N_SITES, CHANNELS, *GRID)),
        keys.ACTUATOR_FORCE: Unbounded((N_ACTUATORS,)),
        keys.OBSERVATION: Unbounded((FLAT_SIZE,)),
        keys.SUCCESS: _flag(),
        keys.BROKEN: _flag(),
    }
