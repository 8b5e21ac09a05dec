"""The agent: which rewards a variant learns from (critic heads), and the parts that learn them.

``variants`` is the registry of reward components and variants; ``rewards`` builds a variant's
:class:`IntrinsicRewards`; ``learner`` the D4PG :class:`Learner`; ``builder`` wires both for a
config, so that any runner (one process, several, distributed) trains the same agent.
"""

from gentlerl.agent.rewards import IntrinsicRewards
from gentlerl.agent.variants import COMPONENTS, VARIANTS, Component, Part, reward_keys

__all__ = ["COMPONENTS", "VARIANTS", "Component", "IntrinsicRewards", "Part", "reward_keys"]
