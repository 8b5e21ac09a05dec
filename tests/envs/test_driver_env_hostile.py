"""DriverHandEnv against a hostile driver and sensor map: a blinding sensor map, a stalled read and an
implausible block force."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import torch

from gentlerl import keys
from tests.helpers import linear_sensor_map


def test_a_blinding_sensor_map_cannot_reach_the_driver_env(driver_env):
    from gentlerl.envs import SimulatedDriver

    sensor_map, _ = linear_sensor_map()
    sensor_map.force_knots.zero_()
    with pytest.raises(ValueError, match="spans 0 N"):
        driver_env(SimulatedDriver(seed=0), "touch", sensor_map=sensor_map)


class _StallingDriver:
    """A scripted driver whose ``read`` stalls from the ``stall_at``-th read on."""

    def __init__(self, stall_at: int, block: float | None = None) -> None:
        from gentlerl.envs.driver import DriverSpec

        self.spec = DriverSpec(-np.ones(20), np.ones(20), has_block_force=block is not None)
        self.reads, self.stall_at, self.block = 0, stall_at, block
        self.commands: list[np.ndarray] = []
        self.release = threading.Event()

    def reset(self) -> np.ndarray:
        return np.zeros(20)

    def read(self):
        from gentlerl.envs.driver import HandReading

        self.reads += 1
        if self.reads >= self.stall_at:
            self.release.wait(5.0)
        return HandReading(np.zeros(24), np.zeros(24), np.full((5, 1), 1000.0), self.block)

    def command(self, targets: np.ndarray) -> None:
        self.commands.append(np.array(targets))

    def close(self) -> None:
        self.release.set()


def test_a_stalled_read_ends_the_episode_safely_and_says_so(driver_env):
    from gentlerl.envs.driver import DriverTimeout

    driver = _StallingDriver(stall_at=4)  # tare + reset read, one step, then a stall
    env = driver_env(driver, "touch", sensor_map=linear_sensor_map()[0], read_timeout=0.2)
    td = env.reset()
    td = env.step(td.set(keys.ACTION, torch.ones(20)))["next"]
    held = driver.commands[-1]
    with pytest.warns(RuntimeWarning, match="no reading within 0.2 s: episode ended"):
        out = env.step(td.set(keys.ACTION, torch.ones(20)))["next"]
    assert out[keys.TERMINATED].item() and out[keys.WATCHDOG].item() and env.read_timeouts == 1
    np.testing.assert_allclose(driver.commands[-1], held)  # the last targets, re-commanded
    with pytest.raises(DriverTimeout, match="still stalled"):
        env.reset()
    driver.release.set()
    for bad in (0, -1.0, float("nan"), "1"):
        with pytest.raises(ValueError, match="read_timeout"):
            driver_env(_StallingDriver(99), sensor_map=linear_sensor_map()[0], read_timeout=bad)


def test_an_implausible_block_force_is_refused(driver_env):
    env = driver_env(_StallingDriver(99, block=-50.0), sensor_map=linear_sensor_map()[0])
    with pytest.raises(ValueError, match="'block_force'=-50.0 N is implausible"):
        env.reset()
