"""The D4PG agent: the multi-head learner and the builder that wires it for a config.

``learner`` holds the D4PG :class:`Learner` (loss, optimiser, target updates) of one seed or of
several as one step over a leading seed axis; ``builder`` wires the policy, the learner, the
rewards (:mod:`gentlerl.rewards`) and the replay for a config, so that any runner (one process,
several, distributed) trains the same agent. Names are imported on first use
(:mod:`gentlerl.lazy`).

The reward side moved to :mod:`gentlerl.rewards` in 0.2.0; its old names here
(``IntrinsicRewards``, ``COMPONENTS``, ``VARIANTS``, ``Component``, ``Part``, ``reward_keys``)
warn and forward until 0.3.0.
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.agent.builder": ("AgentBuilder",),
        "gentlerl.agent.learner": ("Learner", "SeedBatchedLearner", "TrainingState"),
    },
    deprecated={
        name: ("gentlerl.rewards", name)
        for name in (
            "IntrinsicRewards",
            "COMPONENTS",
            "VARIANTS",
            "Component",
            "Part",
            "reward_keys",
        )
    },
)
