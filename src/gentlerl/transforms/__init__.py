"""TorchRL transforms that write the paper's gentleness rewards (impact, penalty, surprise, ICM).

Each transform reads a transition's root entries (``s_t``, ``a_t``) and ``"next"`` entries
(``s_{t+1}``) and writes its reward under ``"next"``, so it works

- appended to an env (``TransformedEnv``, ``ParallelEnv``): ``_step`` sees both halves, and
  ``ImpactPenalty`` writes a zero ``impact`` at reset (no spurious first-step impact);
- on a batch from a collector, alone or in a ``Compose``: ``forward(batch)`` fills
  ``("next", key)`` for every transition;
- as a replay-buffer transform, at sample time (the rewards then use the *current* target model).

gentlerl's training loop uses the second form: it applies :attr:`RewardStack.transform` to each
collected batch *before* writing it to the n-step replay buffer, because TorchRL's
``MultiStepTransform`` sums every reward key over the n steps at write time, so the intrinsic
rewards must already be in the transitions (they are computed with the target model of that
moment, which the paper refreshes only every 5000 / 1000 model updates anyway).

The model-owning transforms (``DynamicsSurprise``, ``PenaltySurprise``, ``ICMReward``) share their
networks with a TorchRL ``LossModule`` (``EnsembleModelLoss`` / ``ICMLoss``), like TorchRL's
``RNDTransform`` / ``RNDLoss`` pair: the loss trains the model, the transform reads it (and
``Transform.clone`` keeps sharing it). Append them to the batched env (``TransformedEnv(
ParallelEnv(...), stack.transform)``), not inside the workers: a worker process would hold a copy
of the networks that the loss's updates never reach. :func:`make_reward_transforms` builds the
whole stack for a paper variant.
"""

from gentlerl.transforms.base import ModelRewardTransform, TransitionTransform
from gentlerl.transforms.calibration import TouchCalibration
from gentlerl.transforms.icm import ICMReward
from gentlerl.transforms.impact import ImpactPenalty
from gentlerl.transforms.stack import HAND_FEATURES, VARIANTS, RewardStack, make_reward_transforms
from gentlerl.transforms.surprise import DynamicsSurprise, PenaltySurprise
from gentlerl.transforms.wear import ForcePenalty, TorquePenalty

#: The paper's name for the ICM baseline transform.
ICM = ICMReward

__all__ = [
    "HAND_FEATURES",
    "ICM",
    "VARIANTS",
    "DynamicsSurprise",
    "ForcePenalty",
    "ICMReward",
    "ImpactPenalty",
    "ModelRewardTransform",
    "PenaltySurprise",
    "RewardStack",
    "TorquePenalty",
    "TouchCalibration",
    "TransitionTransform",
    "make_reward_transforms",
]
