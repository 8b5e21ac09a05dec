"""TorchRL transforms that write the paper's gentleness rewards (impact, penalty, surprise, ICM).

Each transform reads a transition's root entries (``s_t``, ``a_t``) and ``"next"`` entries
(``s_{t+1}``) and writes its reward under ``"next"``, so it works

- appended to an env (``TransformedEnv``, ``ParallelEnv``): ``_step`` sees both halves, and
  ``ImpactPenalty`` writes a zero ``impact`` at reset (no spurious first-step impact);
- on a batch from a collector, alone or in a ``Compose``: ``forward(batch)`` fills
  ``("next", key)`` for every transition;
- as a replay-buffer transform, at sample time (the rewards then use the *current* target model).

gentlerl's training loop uses the second form: it applies :attr:`IntrinsicRewards.transform` to each
collected batch *before* writing it to the n-step replay buffer, because TorchRL's
``MultiStepTransform`` sums every reward key over the n steps at write time, so the rewards must
already be in the transitions. With ``rescore_surprise`` (the default) the penalty surprise is
then scored again when a transition is sampled, from the raw steps of its window, with the
target model of that update (:func:`gentlerl.data.rescore_windows`); the paper's reading
(``rescore_surprise=false``, the ``paper`` scale) keeps the value scored at collection.

The model-reading transforms (``DynamicsSurprise``, ``PenaltySurprise``, ``ICMReward``) receive
their model and the parameters to read it with, like TorchRL's ``RNDTransform``; the wiring
(:mod:`gentlerl.rewards`) hands the same model to the ``LossModule`` that trains it, so the
transforms import no loss. ``Transform.clone`` keeps sharing the model. Append them to the
batched env (``TransformedEnv(ParallelEnv(...), rewards.transform)``), not inside the workers: a
worker process would hold a copy of the networks that the loss's updates never reach, so a
model-reading transform refuses to run in another process than the one it was built in.

A variant's transforms, their models and the single-critic helpers (``SumRewards``,
``RescoreRewards``) are built by :class:`gentlerl.rewards.IntrinsicRewards`, the drop-in package.
"""

from gentlerl.lazy import lazy_exports
from gentlerl.transforms.base import ModelRewardTransform, TransitionTransform
from gentlerl.transforms.icm import ICMReward
from gentlerl.transforms.impact import ExcessPenalty, ImpactPenalty, NonFiniteForceError
from gentlerl.transforms.sensor_map import TouchSensorMap
from gentlerl.transforms.surprise import DynamicsSurprise, PenaltySurprise
from gentlerl.transforms.wear import ForcePenalty, TorquePenalty

#: The paper's name for the ICM baseline transform.
ICM = ICMReward

__all__ = [
    "ICM",
    "DynamicsSurprise",
    "ExcessPenalty",
    "ForcePenalty",
    "ICMReward",
    "ImpactPenalty",
    "NonFiniteForceError",
    "ModelRewardTransform",
    "PenaltySurprise",
    "TorquePenalty",
    "TouchSensorMap",
    "TransitionTransform",
]

# PEP 562: an earlier name warns and returns its new one until 0.3.0 ("calibration" now names
# the critics' check, ``gentlerl calibration``); any other missing name fails as Python's does.
__getattr__ = lazy_exports(
    "gentlerl.transforms",
    {},
    deprecated={"TouchCalibration": ("gentlerl.transforms", "TouchSensorMap")},
)[0]
