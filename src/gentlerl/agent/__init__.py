"""The agent: which rewards a variant learns from (critic heads), and the parts that learn them.

``variants`` is the registry of reward components and variants; ``rewards`` builds a variant's
:class:`IntrinsicRewards`; ``learner`` the D4PG :class:`Learner`; ``builder`` wires both for a
config, so that any runner (one process, several, distributed) trains the same agent. Names are
imported on first use (:mod:`gentlerl.lazy`): the variants' names need no torch.
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.agent.rewards": ("IntrinsicRewards",),
        "gentlerl.agent.variants": ("COMPONENTS", "VARIANTS", "Component", "Part", "reward_keys"),
    },
)
