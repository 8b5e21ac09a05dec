"""The drop-in gentleness rewards: what any TorchRL agent adds to learn a task gently.

``IntrinsicRewards`` builds a variant's reward transforms (impact penalty, surprise, ICM), the
models they read, their losses, optimisers, schedule and 1-step buffer; ``from_env`` sizes them
from an env's specs. For an agent with one critic (SAC, TD3, PPO), ``SumRewards`` sums the
components into one ``reward``, and ``RescoreRewards`` (``IntrinsicRewards.rescore_transform()``)
scores the curiosity of each sampled batch again with the current models. "Rescore" is the one
verb for "score again at sampling": ``GentlenessConfig.rescore_surprise`` asks for it, a 1-step
replay buffer does it with ``rescore_transform()``, an n-step one with
``IntrinsicRewards.rescore_windows`` (:func:`gentlerl.data.rescore_windows`, beside the
``NStepWriter`` that keeps the windows). ``variants`` is the registry of reward components (one
critic head each) and the paper's variants. Names are imported on first use
(:mod:`gentlerl.lazy`): the variants' names need no torch.

Example (a SAC user's replay buffer)::

    rewards = IntrinsicRewards.from_env(env, "r+rf+rsp")
    reward_sum = SumRewards(rewards.reward_keys)
    rb.append_transform(rewards.rescore_transform(reward_sum))
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.rewards.intrinsic": ("IntrinsicRewards",),
        "gentlerl.rewards.lagrangian": ("CostLagrangian",),
        "gentlerl.rewards.multiplier": ("ImpactMultiplier",),
        "gentlerl.rewards.rescore": ("RescoreRewards",),
        "gentlerl.rewards.sum": ("SumRewards",),
        "gentlerl.rewards.variants": ("COMPONENTS", "VARIANTS", "Component", "Part", "reward_keys"),
    },
)
