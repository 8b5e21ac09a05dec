"""Evaluation rollouts without exploration noise."""

from __future__ import annotations

import torch
from tensordict.nn import TensorDictModule
from torchrl.envs import EnvBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys


@torch.no_grad()
def evaluate(
    env: EnvBase, actor: TensorDictModule, episodes: int, max_steps: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run ``episodes`` deterministic episodes; ``env`` must write ``impact`` (``ImpactPenalty``).

    Returns the summary (``success_rate``, ``broken_rate``, ``max_impact_mean``, ``return``) and
    one dict per episode (``success``, ``broken``, ``max_impact`` in N, ``return``).
    """
    per_episode = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            rollout = env.rollout(max_steps, actor, break_when_any_done=True)
            nxt = rollout.get("next")
            per_episode.append(
                {
                    "success": float(nxt.get(keys.SUCCESS).any()),
                    "broken": float(nxt.get(keys.BROKEN).any()),
                    "max_impact": float(nxt.get(keys.IMPACT).max()),
                    "return": float(nxt.get(keys.REWARD).sum()),
                }
            )
    n = max(len(per_episode), 1)
    summary = {
        "success_rate": sum(e["success"] for e in per_episode) / n,
        "broken_rate": sum(e["broken"] for e in per_episode) / n,
        "max_impact_mean": sum(e["max_impact"] for e in per_episode) / n,
        "return": sum(e["return"] for e in per_episode) / n,
    }
    return summary, per_episode
