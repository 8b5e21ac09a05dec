"""``SimulatedDriver``: the MuJoCo hand behind the driver protocol, with BioTac-like sensors.

It lets the whole real-robot path (driver -> sensor map -> watchdog -> ``DriverHandEnv``) run and
be tested without hardware. The touch grids' normal (and tangential) forces go through
:class:`BioTacModel`, so the env sees raw sensor counts as a real hand would, and needs a fitted sensor map
(:class:`~gentlerl.transforms.TouchSensorMap`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from gentlerl.envs.contacts import settled
from gentlerl.envs.driver import N_JOINTS, N_SITES, DriverSpec, HandReading, check_targets
from gentlerl.envs.factory import make_dm_env
from gentlerl.envs.hand import CONTROL_TIMESTEP


@dataclass
class BioTacModel:
    r"""A pressure sensor per fingertip channel, in ADC counts (a BioTac's PDC channel):

    .. math:: raw = b_i + g_i \log(1 + f / k_i) + d_t + \epsilon, \quad
              \epsilon \sim N(0, \sigma^2), \; d_{t+1} = d_t + N(0, \sigma_d^2)

    rounded to whole counts: monotone and saturating in the force ``f`` (N), with a per-sensor
    baseline ``b_i``, gain ``g_i`` and knee ``k_i`` (the nominal values spread by ``spread``), white
    noise and a random-walk baseline drift ``d_t`` (thermal drift, advanced once per control step).
    """

    baseline: float = 2000.0
    gain: float = 400.0
    knee: float = 2.0
    spread: float = 0.15
    noise: float = 2.0
    drift: float = 0.2
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("gain", "knee"):
            if not getattr(self, name) > 0:
                raise ValueError(f"BioTacModel.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("spread", "noise", "drift"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"BioTacModel.{name} must be >= 0, got {getattr(self, name)!r}")
        # The sensors' physical parameters: fixed by ``seed`` for the life of the hand.
        jitter = 1.0 + self.spread * np.random.RandomState(self.seed).uniform(
            -1.0, 1.0, size=(3, N_SITES, 1)
        )
        self.params = self.baseline * jitter[0], self.gain * jitter[1], self.knee * jitter[2]
        self.reseed(self.seed)

    def reseed(self, seed: int) -> None:
        """A new noise stream and the drift back to 0 (the sensors' parameters are kept)."""
        self.rng = np.random.RandomState(seed + 1)
        self.offset = np.zeros((N_SITES, 1))

    def advance(self) -> None:
        """One control step of baseline drift."""
        self.offset = self.offset + self.rng.normal(0.0, self.drift, size=self.offset.shape)

    def __call__(self, force: np.ndarray) -> np.ndarray:
        """Raw counts of the forces ``[5, C]`` (N, >= 0)."""
        b, g, k = self.params
        clean = b + g * np.log1p(np.maximum(force, 0.0) / k) + self.offset
        return np.round(clean + self.rng.normal(0.0, self.noise, size=np.shape(force)))


class SimulatedDriver:
    """The simulated Shadow Hand as a :class:`~gentlerl.envs.driver.HandDriver`.

    ``command`` sets the position targets and steps MuJoCo for one 50 ms control period; ``read``
    returns joints, raw BioTac-like tactile readings of the first ``tactile_channels`` touch
    channels, the normal force on the block (the paper's force/torque sensor) and the actuator
    forces. The block is
    placed as in the simulated task (``randomize_block``, ``block_range``).

    Args:
        seed: block placement, sensor parameters and noise (:meth:`seed`: placement and noise).
        tactile_channels: 1 (pressure, as the paper's BioTacs) to 3 (also the tangential ones).
        sensor: the sensor model (default :class:`BioTacModel` with ``seed``).
        **task_kwargs: ``regime`` (the hand's physics regime, a name in
            ``gentlerl.envs.hand.REGIMES``),
            ``randomize_block``, ``block_range``, ``block_pos``.
    """

    def __init__(
        self,
        seed: int = 0,
        *,
        tactile_channels: int = 1,
        sensor: BioTacModel | None = None,
        **task_kwargs,
    ) -> None:
        self._env = make_dm_env("explore", seed=seed, time_limit=10**9, **task_kwargs)
        self.physics = self._env.physics
        low, high = self.physics.model.actuator_ctrlrange.T
        self.spec = DriverSpec(
            low,
            high,
            tactile_channels=tactile_channels,
            has_block_force=True,
            has_actuator_force=True,
        )
        self.sensor = sensor or BioTacModel(seed=seed)
        self.n_sub_steps = int(round(CONTROL_TIMESTEP / self.physics.model.opt.timestep))
        self._block_geom = self.physics.model.geom("block").id
        self._wrench = np.zeros(6)
        self._scratch = mujoco.MjData(self.physics.model.ptr)

    def seed(self, seed: int) -> None:
        """Re-seed the block placement and the sensor noise."""
        self._env.task._random = np.random.RandomState(seed)
        self.sensor.reseed(seed)

    def reset(self) -> np.ndarray:
        self._env.reset()
        return self.physics.data.ctrl.copy()

    def command(self, targets: np.ndarray) -> None:
        self.physics.data.ctrl[:] = check_targets(targets, self.spec, "command")
        self.physics.step(self.n_sub_steps)
        self.sensor.advance()

    def true_touch(self) -> np.ndarray:
        """The simulated touch ``[5, 3]`` (N) the sensors see: the sensor map's ground truth."""
        return self.physics.touch()

    def block_force(self) -> float:
        """Sum of the normal contact forces on the block (N), of the current state's contacts
        (:func:`~gentlerl.envs.contacts.settled`: dm_control's step leaves the constraint forces
        of the step before, which read as negative normals)."""
        model = self.physics.model.ptr
        data = settled(model, self.physics.data.ptr, self._scratch)
        total = 0.0
        for i in range(data.ncon):
            contact = data.contact[i]
            if self._block_geom in (contact.geom1, contact.geom2):
                mujoco.mj_contactForce(model, data, i, self._wrench)
                total += self._wrench[0]
        return total

    def read(self) -> HandReading:
        data = self.physics.data
        touch = self.true_touch()[:, : self.spec.tactile_channels]
        return HandReading(
            joint_pos=data.qpos[:N_JOINTS].copy(),
            joint_vel=data.qvel[:N_JOINTS].copy(),
            tactile=self.sensor(touch),
            block_force=self.block_force(),
            actuator_force=data.actuator_force.copy(),
        )

    def close(self) -> None:
        self._env.close()


# Per fingertip, the actuators and directions that press it into the block (ff, mf, rf) or into
# the palm (lf, th): a scripted pressing session loads every sensor.
PRESSES: tuple[dict[str, float], ...] = (
    {"A_FFJ2": 1.0},
    {"A_MFJ2": 1.0},
    {"A_RFJ2": 1.0},
    {"A_LFJ3": 1.0, "A_LFJ2": 1.0, "A_LFJ1": 1.0},
    {"A_THJ4": 1.0, "A_THJ3": 1.0, "A_THJ2": 1.0, "A_THJ1": -1.0, "A_THJ0": -1.0},
)


def pressing_session(
    driver: SimulatedDriver, rates: tuple[float, ...] = (0.01, 0.02, 0.04), hold: int = 10
) -> tuple[np.ndarray, np.ndarray]:
    """A scripted session to fit a sensor map: each fingertip in turn pressed and released at each
    ``rate``.

    A press moves the fingertip's :data:`PRESSES` actuators by ``rate`` x their range per control
    step to their limit, holds ``hold`` steps, and returns. Every step records the raw tactile
    reading and, as the reference force, the simulated touch (what a load cell pressed on the
    fingertip would read on a real hand).

    Returns:
        ``(raw, force)``, both ``[N, 5, tactile_channels]``.
    """
    model = driver.physics.model
    index = {model.actuator(i).name.removeprefix("robot0:"): i for i in range(model.nu)}
    low, high = driver.spec.target_low, driver.spec.target_high
    raw, force = [], []
    for press in PRESSES:
        for rate in rates:
            home = driver.reset()
            direction = np.zeros_like(home)
            for name, sign in press.items():
                direction[index[name]] = sign
            n = int(np.ceil(1.0 / rate))
            ramp = [*range(1, n + 1), *[n] * hold, *range(n - 1, -1, -1)]
            for k in ramp:
                driver.command(np.clip(home + direction * k * rate * (high - low), low, high))
                raw.append(driver.read().tactile)
                force.append(driver.true_touch()[:, : driver.spec.tactile_channels])
    return np.stack(raw), np.stack(force)
