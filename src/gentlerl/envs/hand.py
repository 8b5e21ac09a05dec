"""dm_control Physics and Tasks of the gentle-touch experiments (Huang et al. 2019, "Tasks").

Control at 20 Hz: each control step runs ``n_sub_steps`` MuJoCo steps of 2 ms (25 x 2 ms = 50 ms).
The action is a *delta position* in [-1, 1]^20: scaled by ``action_scale`` x each actuator's
ctrl range, added to the current position targets, clipped to the ctrl ranges.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from dm_control.mujoco import Physics
from dm_control.suite import base
from dm_env import specs

from gentlerl import keys
from gentlerl.envs.assets import CHANNELS, FINGERTIPS, GRID, TOUCH_SITES

CONTROL_TIMESTEP = 0.05  # 20 Hz
# Block centre (world frame), matching assets.BLOCK_QUAT: the plate lies flat on the distal pads
# of the first three fingers when their knuckles (J2) are flexed by 0.75 rad.
BLOCK_POS = (1.0, 0.8124, 0.2111)
# The plate's normal (world frame), pointing away from the finger pads: ``block_gap`` moves the
# block along it.
BLOCK_NORMAL = (0.0, float(np.sin(0.75)), float(np.cos(0.75)))

#: The hand's physics regimes (``make_dm_env(..., regime=NAME)``): action scale (fraction of each
#: actuator's ctrl range per step), finger actuator gain (x gymnasium-robotics' kp and force
#: range) and block gap (m, along :data:`BLOCK_NORMAL`), chosen from measured presses and random
#: actions. ``paper`` puts the hand in the paper's regime: a naive full press breaks
#: the fragile block (5 of 5 episodes, 8.2 N), uniformly random actions exceed 5 N in 74 % of the
#: episodes that touch anything, and a gradual scripted press still succeeds without breaking it
#: (max impact 1.0 N). ``easy`` is the earlier setting, where nothing breaks the block unless it
#: tries hard (full press: 2.2 N, random actions never above 5 N).
REGIMES: dict[str, dict[str, float]] = {
    "paper": {"action_scale": 0.07, "actuator_gain": 3.0, "block_gap": 0.0},
    "easy": {"action_scale": 0.02, "actuator_gain": 3.0, "block_gap": 0.0},
}
DEFAULT_REGIME = "paper"


# Layout of the float32 observation buffer a task fills each step (one allocation per step):
# joint_pos [24] | joint_vel [24] | touch [5, 3] | touch_grid [5, 3, 4, 4] | actuator_force [20].
# The first 63 values are the flat ``observation`` the learner reads.
N_JOINTS = 24
N_ACTUATORS = 20
N_TOUCH = len(TOUCH_SITES) * CHANNELS
N_GRID = N_TOUCH * GRID[0] * GRID[1]
FLAT_SIZE = 2 * N_JOINTS + N_TOUCH  # 63
GRID_END = FLAT_SIZE + N_GRID
OBS_SLICES = {
    keys.JOINT_POS: (slice(0, N_JOINTS), (N_JOINTS,)),
    keys.JOINT_VEL: (slice(N_JOINTS, 2 * N_JOINTS), (N_JOINTS,)),
    keys.TOUCH: (slice(2 * N_JOINTS, FLAT_SIZE), (len(TOUCH_SITES), CHANNELS)),
    keys.TOUCH_GRID: (slice(FLAT_SIZE, GRID_END), (len(TOUCH_SITES), CHANNELS, *GRID)),
    keys.ACTUATOR_FORCE: (slice(GRID_END, GRID_END + N_ACTUATORS), (N_ACTUATORS,)),
}
OBS_SIZE = GRID_END + N_ACTUATORS
_TOUCH_SLICE, _TOUCH_SHAPE = OBS_SLICES[keys.TOUCH]


class HandPhysics(Physics):
    """Physics with named accessors for the observations (dm_control convention)."""

    @cached_property
    def _tip_geoms(self) -> np.ndarray:
        return np.array([self.model.geom(f"robot0:C_{f}distal").id for f in FINGERTIPS])

    @cached_property
    def _block_geom(self) -> int:
        return self.model.geom("block").id

    def observation_buffer(self) -> np.ndarray:
        """A fresh float32 ``[OBS_SIZE]`` buffer laid out as :data:`OBS_SLICES`."""
        data = self.data
        grid = data.sensordata[-N_GRID:]
        # |grid| summed per site and channel in float64 (as ``np.abs(...).sum(-1)``), then one
        # concatenate casts everything to float32: one allocation, ~2x faster than item-wise writes.
        touch = np.add.reduce(np.abs(grid.reshape(N_TOUCH, -1)), axis=-1)
        parts = (data.qpos[:N_JOINTS], data.qvel[:N_JOINTS], touch, grid, data.actuator_force)
        return np.concatenate(parts, dtype=np.float32)

    def touch_grid(self) -> np.ndarray:
        """Raw touch grids ``[5, 3, 4, 4]`` (N): normal, then two tangential channels."""
        return self.data.sensordata[-N_GRID:].reshape(OBS_SLICES[keys.TOUCH_GRID][1]).copy()

    def touch(self) -> np.ndarray:
        """Per fingertip and channel, the sum of |value| over the 4x4 grid: ``[5, 3]`` (N)."""
        return np.abs(self.touch_grid()).sum(axis=(-2, -1))

    def block_contact(self) -> np.ndarray:
        """``[5]`` bool: whether each fingertip's distal phalanx touches the block."""
        n = self.data.ncon
        g1, g2 = self.data.contact.geom1[:n], self.data.contact.geom2[:n]
        block = self._block_geom
        # Per contact, the geom touching the block (-1: the block is not in it); a broadcast
        # comparison with the 5 tips is ~3x faster than ``np.isin`` on a handful of contacts.
        others = np.where(g1 == block, g2, np.where(g2 == block, g1, -1))
        return (self._tip_geoms[:, None] == others).any(axis=-1)


def _check_non_negative(**values: float) -> None:
    for name, value in values.items():
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")


class Explore(base.Task):
    """No task reward: the hand moves its fingers near a fixed block for ``time_limit`` steps."""

    def __init__(
        self,
        *,
        action_scale: float = REGIMES[DEFAULT_REGIME]["action_scale"],
        randomize_block: bool = True,
        block_range: float = 0.005,
        block_pos: tuple[float, float, float] = BLOCK_POS,
        block_gap: float = 0.0,
        random: int | np.random.RandomState | None = None,
    ) -> None:
        _check_non_negative(block_range=block_range)
        if not 0 < action_scale <= 1:
            raise ValueError(f"action_scale must be in (0, 1], got {action_scale!r}")
        super().__init__(random=random)
        self.action_scale = action_scale
        self.randomize_block = randomize_block
        self.block_range = block_range
        self.block_pos = np.asarray(block_pos, dtype=np.float64)
        if self.block_pos.shape != (3,):
            raise ValueError(f"block_pos must be (x, y, z), got {block_pos!r}")
        if not (np.isfinite(block_gap) and -0.01 <= block_gap <= 0.05):
            raise ValueError(f"block_gap must be in [-0.01, 0.05] m, got {block_gap!r}")
        self.block_pos = self.block_pos + block_gap * np.asarray(BLOCK_NORMAL)
        self.buffer: np.ndarray | None = None  # float32 [OBS_SIZE], laid out as OBS_SLICES
        self.touch: np.ndarray | None = None  # [5, 3] view of ``buffer``
        self.success = False
        self.broken = False

    # -- episode -------------------------------------------------------------------------
    def initialize_episode(self, physics: HandPhysics) -> None:
        with physics.reset_context():
            physics.data.qpos[:] = 0.0
            physics.data.qvel[:] = 0.0
            low, high = physics.model.actuator_ctrlrange.T
            physics.data.ctrl[:] = np.clip(0.0, low, high)
            block = physics.model.body("block").mocapid[0]
            offset = np.zeros(3)
            if self.randomize_block:
                offset[:2] = self.random.uniform(-self.block_range, self.block_range, size=2)
            physics.data.mocap_pos[block] = self.block_pos + offset
        self._observe(physics)
        self.success = self.broken = False

    def before_step(self, action: np.ndarray, physics: HandPhysics) -> None:
        low, high = physics.model.actuator_ctrlrange.T
        physics.data.ctrl[:] = self.next_targets(physics.data.ctrl, action, low, high)

    def next_targets(
        self, targets: np.ndarray, action: np.ndarray, low: np.ndarray, high: np.ndarray
    ) -> np.ndarray:
        """The position targets after a delta-position ``action`` in [-1, 1]^n (paper, "Agent").

        ``clip(targets + clip(action, -1, 1) * action_scale * (high - low), low, high)``; a
        wrong-shaped or non-finite ``action`` raises ``ValueError``.
        """
        action = np.asarray(action, dtype=np.float64)
        if action.shape != np.shape(low):
            raise ValueError(f"action must have shape {np.shape(low)}, got {action.shape}")
        if not np.isfinite(action).all():
            raise ValueError(f"action must be finite, got {action}")
        # ``np.minimum(np.maximum(...))`` is ``np.clip`` (the same values) without its ~1 us of
        # Python dispatch, twice per control step.
        delta = np.minimum(np.maximum(action, -1.0), 1.0) * self.action_scale * (high - low)
        return np.minimum(np.maximum(targets + delta, low), high)

    def after_step(self, physics: HandPhysics) -> None:
        previous = self._observe(physics)
        if type(self).update_outcome is Explore.update_outcome:
            return  # no outcome rule to feed: skip the contact look-up
        touch = self.touch
        # Contacts are only looked up when a fingertip senses something (rare: keeps steps fast).
        on_block = physics.block_contact() if touch.any() else np.zeros(len(touch), dtype=bool)
        self.update_outcome(touch, previous, on_block)

    def _observe(self, physics: HandPhysics) -> np.ndarray:
        """Read this step's observations into :attr:`buffer`; return the previous ``touch``."""
        previous = self.touch
        self.buffer = physics.observation_buffer()
        self.touch = self.buffer[_TOUCH_SLICE].reshape(_TOUCH_SHAPE)
        return previous

    @property
    def observation(self) -> dict[str, np.ndarray]:
        """This step's observations: views of :attr:`buffer` (``{}`` before the first reset)."""
        if self.buffer is None:
            return {}
        return {
            key: self.buffer[where].reshape(shape) for key, (where, shape) in OBS_SLICES.items()
        }

    def update_outcome(self, touch: np.ndarray, previous: np.ndarray, on_block: np.ndarray) -> None:
        """Set :attr:`success` / :attr:`broken` for this step (nothing to do without a task).

        ``touch`` / ``previous``: ``[5, 3]`` readings after / before the step; ``on_block``:
        ``[5]`` which fingertips touch the block (self-contacts between fingers do not count).
        """

    # -- dm_control Task API ---------------------------------------------------------------
    def action_spec(self, physics: HandPhysics) -> specs.BoundedArray:
        return specs.BoundedArray((physics.model.nu,), np.float64, -1.0, 1.0, name="action")

    def get_observation(self, physics: HandPhysics) -> dict[str, np.ndarray]:
        """float32 ``joint_pos`` [24], ``joint_vel`` [24], ``touch`` [5, 3], ``touch_grid``
        [5, 3, 4, 4], ``actuator_force`` [20]: views of :attr:`buffer`, read once per step in
        ``after_step``."""
        return self.observation

    def get_reward(self, physics: HandPhysics) -> float:
        return 0.0

    def get_termination(self, physics: HandPhysics) -> float | None:
        return None


class Touch(Explore):
    """Reward +1 and termination when any fingerpad presses the block with > ``force_threshold`` N."""

    def __init__(
        self, *, force_threshold: float = 5.0, success_reward: float = 1.0, **kwargs
    ) -> None:
        _check_non_negative(force_threshold=force_threshold)
        super().__init__(**kwargs)
        self.force_threshold = force_threshold
        self.success_reward = success_reward

    def update_outcome(self, touch: np.ndarray, previous: np.ndarray, on_block: np.ndarray) -> None:
        self.success = bool((touch[on_block, 0] > self.force_threshold).any())

    def get_reward(self, physics: HandPhysics) -> float:
        return self.success_reward if self.success else 0.0

    def get_termination(self, physics: HandPhysics) -> float | None:
        return 0.0 if self.success else None


class Fragile(Touch):
    """Touch with a fragile block: success pays +5; an impact > ``break_impact`` N at any fingertip
    (force increase summed over channels in one control step, paper eq. 1) breaks the block:
    reward ``break_reward`` (-0.5) and termination."""

    def __init__(
        self,
        *,
        break_impact: float = 3.0,
        break_reward: float = -0.5,
        success_reward: float = 5.0,
        **kwargs,
    ) -> None:
        _check_non_negative(break_impact=break_impact)
        super().__init__(success_reward=success_reward, **kwargs)
        self.break_impact = break_impact
        self.break_reward = break_reward

    def update_outcome(self, touch: np.ndarray, previous: np.ndarray, on_block: np.ndarray) -> None:
        impact = np.clip(touch - previous, 0.0, None).sum(-1)
        self.broken = bool((impact[on_block] > self.break_impact).any())
        self.success = not self.broken and bool((touch[on_block, 0] > self.force_threshold).any())

    def get_reward(self, physics: HandPhysics) -> float:
        if self.broken:
            return self.break_reward
        return super().get_reward(physics)

    def get_termination(self, physics: HandPhysics) -> float | None:
        return 0.0 if (self.success or self.broken) else None
