"""Networks: the D4PG actor and fused multi-head critic, and the model ensembles."""

from gentlerl.models.actor import make_actor, make_exploration_policy
from gentlerl.models.critic import FusedCritic, make_critic

__all__ = ["FusedCritic", "make_actor", "make_critic", "make_exploration_policy"]
