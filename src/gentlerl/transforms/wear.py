"""Wear penalties beyond the paper: total fingertip force and actuator effort.

The paper's impact penalty (eq. 4) charges the *increase* of force; its future work names other
sources of wear: the force *level* a fingertip holds, and the effort of the actuators. Both
transforms charge an amount above an acceptability threshold (eq. 3), as eq. 4 does, and write a
``[1]`` reward under ``"next"`` that gets its own critic head.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from tensordict import TensorDictBase

from gentlerl import keys
from gentlerl.functional import force_penalty, torque_penalty
from gentlerl.transforms.base import TransitionTransform, check_lam


class _LevelPenalty(TransitionTransform):
    """A penalty of the level ``in_keys[0]`` reaches after the step: ``penalty(s_{t+1}, *lam)``.

    Subclasses set :attr:`penalty`, :attr:`default_lam` and :attr:`default_keys` (in, out).
    """

    penalty: Callable[..., torch.Tensor]
    default_lam: tuple[float, float]
    default_keys: tuple[str, str]

    def __init__(
        self,
        lam: tuple[float, float] | None = None,
        *,
        in_keys: list[str] | None = None,
        out_keys: list[str] | None = None,
    ) -> None:
        lam = self.default_lam if lam is None else lam
        in_keys = in_keys or [self.default_keys[0]]
        out_keys = out_keys or [self.default_keys[1]]
        name = type(self).__name__
        if len(in_keys) != 1 or len(out_keys) != 1:
            raise ValueError(
                f"{name} reads one key and writes one penalty; got in_keys={in_keys}, "
                f"out_keys={out_keys}"
            )
        self.lam = check_lam(name, lam)
        super().__init__(in_keys=in_keys, out_keys=out_keys)
        self.scalar_out_keys = (out_keys[0],)

    def compute(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> dict[str, torch.Tensor]:
        level = self.read(next_tensordict, self.in_keys[0])
        return {self.out_keys[0]: self.penalty(level, *self.lam).unsqueeze(-1)}


class ForcePenalty(_LevelPenalty):
    r"""Writes ``force_penalty`` :math:`r^F_t = -\sum_i (1 - a_\lambda(F^i_{t+1}))\, F^i_{t+1}` ``[1]``
    under ``"next"``, :math:`F^i = \sum_c f^{i,c}` the total force on sensor site ``i``
    (:func:`gentlerl.functional.force_penalty`).

    Works with any force key shaped ``[..., n_sites, n_channels]`` (the hand env's ``touch``).

    Args:
        lam: :math:`\lambda` of the acceptability sigmoid; default ``[2, 8]``: the touch task's
            press (6.6 N in total when slow) costs 0.38, 10 N costs 9.8.
        in_keys: ``[force_key]``; out_keys: ``[penalty_key]``.

    Examples:
        >>> from tensordict import TensorDict
        >>> td = TensorDict({"touch": torch.zeros(5, 3),
        ...                  "next": {"touch": torch.tensor([[8.0, 0, 0]] + [[0.0] * 3] * 4)}})
        >>> ForcePenalty()(td)["next", "force_penalty"]
        tensor([-4.])
    """

    penalty = staticmethod(force_penalty)
    default_lam = (2.0, 8.0)
    default_keys = (keys.TOUCH, keys.FORCE_PENALTY)


class TorquePenalty(_LevelPenalty):
    r"""Writes ``torque_penalty`` :math:`r^\tau_t = -\sum_j (1 - a_\lambda(|\tau^j_{t+1}|))\, |\tau^j_{t+1}|`
    ``[1]`` under ``"next"``, :math:`\tau^j` the force of actuator ``j``
    (:func:`gentlerl.functional.torque_penalty`).

    Reads the hand env's ``actuator_force`` ``[20]`` by default; any ``[..., n_actuators]`` key works.

    Args:
        lam: :math:`\lambda` of the acceptability sigmoid; default ``[4, 1]`` (N m): the ~0.55 N m
            of a knuckle pressing for the touch task costs 0.08, 2 N m costs 1.96.
        in_keys: ``[actuator_force_key]``; out_keys: ``[penalty_key]``.

    Examples:
        >>> from tensordict import TensorDict
        >>> td = TensorDict({"actuator_force": torch.zeros(20),
        ...                  "next": {"actuator_force": torch.tensor([1.0, -1.0] + [0.0] * 18)}})
        >>> TorquePenalty()(td)["next", "torque_penalty"]
        tensor([-1.])
    """

    penalty = staticmethod(torque_penalty)
    default_lam = (4.0, 1.0)
    default_keys = (keys.ACTUATOR_FORCE, keys.TORQUE_PENALTY)
