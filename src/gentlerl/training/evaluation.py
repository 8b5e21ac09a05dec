"""Evaluation rollouts without exploration noise."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.envs import EnvBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys


def _episode_stats(rollout: TensorDictBase) -> list[dict[str, float]]:
    """One dict per row of a ``[B, T]`` rollout, over the steps up to the row's first ``done``."""
    nxt = rollout.get("next")
    done = nxt.get(keys.DONE).reshape(*rollout.shape).int()
    valid = (done.cumsum(-1) - done) == 0  # steps before and at the first done
    impact = nxt.get(keys.IMPACT).reshape(*rollout.shape, -1).amax(-1)
    columns = {
        "success": nxt.get(keys.SUCCESS).reshape(*rollout.shape),
        "broken": nxt.get(keys.BROKEN).reshape(*rollout.shape),
    }
    reward = nxt.get(keys.REWARD).reshape(*rollout.shape)
    return [
        {
            **{name: float(col[b][valid[b]].any()) for name, col in columns.items()},
            "max_impact": float(impact[b][valid[b]].max()),
            "return": float(reward[b][valid[b]].sum()),
        }
        for b in range(rollout.shape[0])
    ]


@torch.no_grad()
def evaluate(
    env: EnvBase, actor: TensorDictModule, episodes: int, max_steps: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run ``episodes`` deterministic episodes; ``env`` must write ``impact`` (``ImpactPenalty``).

    A batched env (batch size ``[N]``) runs ``N`` episodes at a time, each hand until its first
    ``done`` (TorchRL's ``break_when_all_done``); a single env runs them one after the other.
    Returns the summary (``success_rate``, ``broken_rate``, ``max_impact_mean``, ``return``) and
    one dict per episode (``success``, ``broken``, ``max_impact`` in N, ``return``).
    """
    per_episode: list[dict[str, float]] = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        while len(per_episode) < episodes:
            if env.batch_size:
                rollout = env.rollout(
                    max_steps, actor, break_when_any_done=False, break_when_all_done=True
                )
                per_episode += _episode_stats(rollout.reshape(-1, rollout.shape[-1]))
            else:
                rollout = env.rollout(max_steps, actor, break_when_any_done=True)
                per_episode += _episode_stats(rollout.unsqueeze(0))
    per_episode = per_episode[:episodes]
    n = max(len(per_episode), 1)
    summary = {
        "success_rate": sum(e["success"] for e in per_episode) / n,
        "broken_rate": sum(e["broken"] for e in per_episode) / n,
        "max_impact_mean": sum(e["max_impact"] for e in per_episode) / n,
        "return": sum(e["return"] for e in per_episode) / n,
    }
    return summary, per_episode


def rank(result: dict[str, float]) -> tuple[float, float, float]:
    """Order of evaluations: higher success rate, then lower broken rate, then lower mean max
    impact (the gentler of two equally successful policies)."""
    return (result["success_rate"], -result["broken_rate"], -result["max_impact_mean"])
