"""TorchRL transforms that write the paper's gentleness rewards (impact, penalty, surprise, ICM)."""

from gentlerl.transforms.base import ModelRewardTransform, TransitionTransform
from gentlerl.transforms.icm import ICMReward
from gentlerl.transforms.impact import ImpactPenalty
from gentlerl.transforms.stack import HAND_FEATURES, VARIANTS, RewardStack, make_reward_transforms
from gentlerl.transforms.surprise import DynamicsSurprise, PenaltySurprise

__all__ = [
    "HAND_FEATURES",
    "VARIANTS",
    "DynamicsSurprise",
    "ICMReward",
    "ImpactPenalty",
    "ModelRewardTransform",
    "PenaltySurprise",
    "RewardStack",
    "TransitionTransform",
    "make_reward_transforms",
]
