"""ForceWatchdog fails closed: readings it cannot trust trip it."""

from __future__ import annotations

import numpy as np
import pytest

from gentlerl.envs.watchdog import ForceWatchdog


@pytest.mark.parametrize(
    "touch",
    [np.full((5, 1), np.nan), np.full((5, 1), np.inf), np.full((5, 1), -50.0), np.zeros((0,))],
)
def test_the_watchdog_trips_on_readings_it_cannot_trust(touch):
    watchdog = ForceWatchdog(fingertip_limit=3.0)
    assert watchdog.check(touch, None)
    assert watchdog.counts()["fault_trips"] == 1 and watchdog.trips == 1
    assert not watchdog.check(np.zeros((5, 1)), None)


@pytest.mark.parametrize("block", [float("nan"), None, -50.0])
def test_the_block_watchdog_trips_on_a_missing_or_implausible_force(block):
    watchdog = ForceWatchdog(fingertip_limit=None, block_limit=5.0)
    assert watchdog.check(np.zeros((5, 1)), block) and watchdog.fault_trips == 1
