"""Networks: the D4PG actor and fused multi-head critic, and the model ensembles."""

from gentlerl.models.actor import make_actor, make_exploration_policy
from gentlerl.models.critic import FusedCritic, make_critic
from gentlerl.models.ensemble import DynamicsModel, GaussianEnsemble, PenaltyModel
from gentlerl.models.icm import ICMModel
from gentlerl.models.layers import HeadLayerNorm, HeadLinear, RunningNorm

__all__ = [
    "DynamicsModel",
    "FusedCritic",
    "GaussianEnsemble",
    "HeadLayerNorm",
    "HeadLinear",
    "ICMModel",
    "PenaltyModel",
    "RunningNorm",
    "make_actor",
    "make_critic",
    "make_exploration_policy",
]
