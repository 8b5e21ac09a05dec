"""The dm_control ``Environment`` of the hand, with its step split around the physics.

``control.Environment.step`` runs ``task.before_step``, ``physics.step``, ``task.after_step`` and
the reward / termination / time-limit rules in one call. :class:`HandEnvironment` exposes the
parts before and after the physics (:meth:`~HandEnvironment.begin_step`,
:meth:`~HandEnvironment.end_step`), so that a batched env can run the physics of many hands on
threads in between (``mujoco.mj_step`` releases the GIL) while every task rule stays in one place.
"""

from __future__ import annotations

import dm_env
import numpy as np
from dm_control.rl import control


class HandEnvironment(control.Environment):
    """``control.Environment`` with :meth:`begin_step` / :meth:`end_step`; ``step`` is their sum.

    dm_control's rules are kept: the time limit wins over a termination on the same step
    (``discount`` 1.0, a truncation), and ``step`` after the last step starts a new episode.
    """

    @property
    def needs_reset(self) -> bool:
        """Whether the last step ended the episode (the next :meth:`step` resets)."""
        return self._reset_next_step

    @property
    def n_sub_steps(self) -> int:
        """MuJoCo steps per control step."""
        return self._n_sub_steps

    def begin_step(self, action: np.ndarray) -> None:
        """Everything of a control step before the physics (the task's ``before_step``)."""
        self._task.before_step(action, self._physics)

    def step_physics(self) -> None:
        """The ``n_sub_steps`` MuJoCo steps of a control step (releases the GIL)."""
        self._physics.step(self._n_sub_steps)

    def end_step(self) -> tuple[float, float | None]:
        """Everything after the physics: ``(reward, discount)``.

        ``discount`` is None while the episode runs, 0.0 when the task terminates it and 1.0 when
        the time limit truncates it (dm_control's convention).
        """
        self._task.after_step(self._physics)
        reward = self._task.get_reward(self._physics)
        self._step_count += 1
        if self._step_count >= self._step_limit:
            discount = 1.0
        else:
            discount = self._task.get_termination(self._physics)
        if discount is not None:
            self._reset_next_step = True
        return reward, discount

    def step(self, action: np.ndarray) -> dm_env.TimeStep:
        """dm_control's ``Environment.step``, from the three parts above."""
        if self._reset_next_step:
            return self.reset()
        self.begin_step(action)
        self.step_physics()
        reward, discount = self.end_step()
        observation = self._task.get_observation(self._physics)
        if discount is None:
            return dm_env.TimeStep(dm_env.StepType.MID, reward, 1.0, observation)
        return dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, observation)
