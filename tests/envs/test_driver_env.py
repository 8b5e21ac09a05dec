"""DriverHandEnv: specs equal to the simulated env's, the task rules, the watchdog, bad drivers.

The rules are checked with a scripted fake driver (exact forces); the whole path (MuJoCo hand,
BioTac-like sensors, sensor map) with :class:`SimulatedDriver`.
"""

import numpy as np
import pytest
import torch
from torchrl.envs import Compose, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.envs import (
    DriverHandEnv,
    DriverSpec,
    ForceWatchdog,
    Fragile,
    HandReading,
    SimulatedDriver,
    make_dm_env,
)
from gentlerl.envs.factory import TASK_CLASSES, TASKS
from gentlerl.envs.sim_driver import pressing_session
from gentlerl.training.logging import EpisodeStats, episode_transforms
from gentlerl.transforms import TouchSensorMap

A_FFJ2 = 3  # flexing the first finger's knuckle presses its pad into the block


class FakeDriver:
    """Targets in [-1, 1]; reads a scripted force per step through raw = 1000 + 100 f."""

    def __init__(self, forces, block=None):
        self.spec = DriverSpec(-np.ones(20), np.ones(20), has_block_force=block is not None)
        self.forces, self.block, self.t, self.commands = forces, block, 0, []

    def reset(self):
        self.t = 0
        return np.zeros(20)

    def read(self):
        f = np.asarray(self.forces[min(self.t, len(self.forces) - 1)], dtype=float)
        block = None if self.block is None else float(self.block[min(self.t, len(self.block) - 1)])
        return HandReading(np.zeros(24), np.zeros(24), 1000 + 100 * f[:, None], block)

    def command(self, targets):
        self.commands.append(np.array(targets))
        self.t += 1

    def close(self):
        pass


def _linear_sensor_map():
    force = np.linspace(0, 20, 64)[:, None, None] * np.ones((1, 5, 1))
    sensor_map = TouchSensorMap(n_knots=16)
    sensor_map.fit(1000 + 100 * force, force)
    return sensor_map


def _press(env, steps, action=None):
    td = env.reset()
    a = torch.zeros(20)
    a[A_FFJ2] = 1.0
    out = []
    for _ in range(steps):
        td = env.step(td.set(keys.ACTION, a if action is None else action))
        out.append(td["next"].clone())
        if td["next", keys.DONE]:
            break
        td = td["next"]
    return torch.stack(out)


@pytest.fixture(scope="module")
def sim_sensor_map():
    driver = SimulatedDriver(seed=0)
    raw, force = pressing_session(driver, rates=(0.02, 0.04))
    driver.close()
    sensor_map = TouchSensorMap()
    errors = sensor_map.fit(raw, force)
    return sensor_map, errors


def test_specs_match_the_simulated_env_and_check_env_specs(sim_sensor_map, driver_env, hand_env):
    env = driver_env(SimulatedDriver(seed=0), "touch", sensor_map=sim_sensor_map[0])
    check_env_specs(env)
    sim = hand_env("touch", seed=0)
    for key in sim.observation_spec.keys(True, True):
        assert env.observation_spec[key] == sim.observation_spec[key], key
    assert env.action_spec == sim.action_spec
    assert env.full_done_spec == sim.full_done_spec and env.reward_spec == sim.reward_spec


def test_simulated_press_succeeds_with_mapped_touch(sim_sensor_map, driver_env):
    sensor_map, errors = sim_sensor_map
    assert errors["rmse_pressed_N"] < 0.3  # BioTac model: 2-count noise on a ~150-count/N slope
    driver = SimulatedDriver(seed=0)
    env = driver_env(driver, "touch", sensor_map=sensor_map)
    env.set_seed(3)
    steps = _press(env, 80)
    # As in simulation: flexing one knuckle presses the pad into the block until it succeeds.
    assert steps[-1][keys.SUCCESS].item() and steps[-1][keys.TERMINATED].item()
    assert 5 <= len(steps) <= 60 and steps[-1][keys.REWARD].item() == 1.0
    touch = steps[-1][keys.TOUCH][0, 0].item()
    assert abs(touch - driver.true_touch()[0, 0]) < 0.5 and touch > 5.0
    assert abs(steps[-1][keys.BLOCK_FORCE].item() - driver.true_touch()[0, 0]) < 0.5
    torch.testing.assert_close(steps[keys.TOUCH], steps[keys.TOUCH_GRID].sum((-2, -1)))
    effort = torch.from_numpy(driver.physics.data.actuator_force).float()
    torch.testing.assert_close(steps[-1][keys.ACTUATOR_FORCE], effort)
    assert steps[-1][keys.ACTUATOR_FORCE][A_FFJ2] > 0.1  # the knuckle pushes against the block


def test_watchdog_ends_the_episode_and_holds_the_last_safe_targets(sim_sensor_map, driver_env):
    driver = SimulatedDriver(seed=0)
    watchdog = ForceWatchdog(fingertip_limit=2.0)
    env = driver_env(driver, "touch", sensor_map=sim_sensor_map[0], watchdog=watchdog)
    env.set_seed(3)
    steps = _press(env, 80)
    last = steps[-1]
    assert last[keys.WATCHDOG].item() and last[keys.TERMINATED].item()
    assert not last[keys.SUCCESS].item() and not steps[:-1][keys.WATCHDOG].any()
    assert last[keys.TOUCH][:, 0].max() > 2.0 >= steps[-2][keys.TOUCH].sum(-1).max()
    # The targets are the previous step's (one delta of action_scale x 1.571 rad less on A_FFJ2).
    np.testing.assert_allclose(driver.physics.data.ctrl, env.targets)
    assert env.targets[A_FFJ2] == pytest.approx((len(steps) - 1) * env.task.action_scale * 1.571)
    assert watchdog.counts() == {
        "trips": 1,
        "fingertip_trips": 1,
        "block_trips": 0,
        "fault_trips": 0,
        "checks": len(steps),
    }


def test_block_watchdog_and_task_rules_with_a_scripted_driver(driver_env):
    sensor_map = _linear_sensor_map()
    zero, press = [0.0] * 5, [6.0, 0, 0, 0, 0]
    env = driver_env(
        FakeDriver([zero, zero, press], block=[0, 0, 6.0]),
        "touch",
        sensor_map=sensor_map,
        watchdog=ForceWatchdog(fingertip_limit=None, block_limit=8.0),
        tare=False,
    )
    steps = _press(env, 5)  # step 1: nothing; step 2: a 6 N press, block under 8 N: success
    assert len(steps) == 2 and steps[-1][keys.SUCCESS].item() and not steps[-1][keys.WATCHDOG]
    # 4 N in one control step on a fragile block: impact > 3 N breaks it (the sim's rule, eq. 1).
    env = driver_env(
        FakeDriver([zero, zero, [4.0, 0, 0, 0, 0]], block=[1.0]), Fragile(), sensor_map=sensor_map
    )
    steps = _press(env, 5)
    assert steps[-1][keys.BROKEN].item() and steps[-1][keys.REWARD].item() == -0.5
    # Block over its limit: the watchdog ends the episode and re-commands the previous targets.
    driver = FakeDriver([zero], block=[0.0, 0.0, 9.0])
    watchdog = ForceWatchdog(fingertip_limit=None, block_limit=8.0)
    env = driver_env(driver, "touch", sensor_map=sensor_map, watchdog=watchdog, tare=False)
    steps = _press(env, 5)
    assert steps[-1][keys.WATCHDOG].item() and watchdog.block_trips == 1 and len(steps) == 2
    np.testing.assert_allclose(driver.commands[-1], driver.commands[-3])


def test_time_limit_is_truncation(driver_env):
    env = driver_env(FakeDriver([[0.0] * 5]), sensor_map=_linear_sensor_map(), time_limit=3)
    steps = _press(env, 10, action=torch.zeros(20))
    assert len(steps) == 3 and steps[-1][keys.TRUNCATED].item()
    assert not steps[-1][keys.TERMINATED].item()


class _Broken(FakeDriver):
    def __init__(self, field, value):
        super().__init__([[0.0] * 5])
        self.field, self.value = field, value

    def read(self):
        reading = super().read()
        setattr(reading, self.field, self.value)
        return reading


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("tactile", np.zeros((5, 3)), r"'tactile' has shape \(5, 3\), expected \(5, 1\)"),
        ("joint_pos", np.zeros(22), r"'joint_pos' has shape \(22,\), expected \(24,\)"),
        (
            "joint_vel",
            np.r_[np.zeros(23), np.nan],
            r"'joint_vel' has non-finite values at .*\[23\]",
        ),
        ("block_force", 3.0, "'block_force' is set but spec.has_block_force=False"),
        ("actuator_force", np.ones(20), "'actuator_force' is set but spec.has_actuator_force="),
    ],
)
def test_bad_readings_name_the_field(field, value, message, driver_env):
    env = driver_env(_Broken(field, value), sensor_map=_linear_sensor_map())
    with pytest.raises(ValueError, match=message):
        env.reset()


def test_bad_configuration_raises():
    sensor_map = _linear_sensor_map()
    with pytest.raises(ValueError, match=r"sensor_map is for \(5, 3\)"):
        DriverHandEnv(FakeDriver([[0.0] * 5]), sensor_map=TouchSensorMap(n_channels=3))
    with pytest.raises(ValueError, match="not fitted"):
        DriverHandEnv(FakeDriver([[0.0] * 5]), sensor_map=TouchSensorMap())
    with pytest.raises(ValueError, match="no block sensor"):
        DriverHandEnv(
            FakeDriver([[0.0] * 5]),
            sensor_map=sensor_map,
            watchdog=ForceWatchdog(block_limit=10.0),
        )
    with pytest.raises(ValueError, match="unknown task 'push'"):
        DriverHandEnv(FakeDriver([[0.0] * 5]), "push", sensor_map=sensor_map)


@pytest.mark.parametrize("task", TASKS)
def test_every_simulated_task_runs_on_a_driver(task):
    """One task table: the driver env builds each simulated task with the same class."""
    env = DriverHandEnv(FakeDriver([[0.0] * 5]), task, sensor_map=_linear_sensor_map())
    assert type(env.task) is TASK_CLASSES[task] is type(make_dm_env(task).task)


@pytest.mark.parametrize("limit", [0.0, -1.0, float("inf"), float("nan"), "5"])
def test_watchdog_limit_must_be_positive_and_finite(limit):
    with pytest.raises(ValueError, match="fingertip_limit must be a positive finite force"):
        ForceWatchdog(fingertip_limit=limit)
    with pytest.raises(ValueError, match="needs fingertip_limit and/or block_limit"):
        ForceWatchdog(fingertip_limit=None, block_limit=None)


def test_same_seed_same_rollout(sim_sensor_map, driver_env):
    rollouts = []
    for _ in range(2):
        env = driver_env(SimulatedDriver(seed=0), sensor_map=sim_sensor_map[0])
        env.set_seed(5)
        torch.manual_seed(0)
        rollouts.append(env.rollout(20))
    assert (rollouts[0] == rollouts[1]).all()


def test_episode_statistics_count_watchdog_endings(driver_env):
    watchdog = ForceWatchdog(fingertip_limit=None, block_limit=8.0)
    driver = FakeDriver([[0.0] * 5], block=[0.0, 0.0, 9.0])
    env = driver_env(driver, "touch", sensor_map=_linear_sensor_map(), watchdog=watchdog)
    batch = TransformedEnv(env, Compose(*episode_transforms())).rollout(5, break_when_any_done=True)
    batch.set(("collector", "traj_ids"), torch.zeros(len(batch), dtype=torch.long))
    batch.set(("next", keys.IMPACT), torch.zeros(len(batch), 5))
    (episode,) = EpisodeStats([keys.REWARD]).update(batch)
    assert episode["watchdog"] == 1.0 and episode["length"] == 2
