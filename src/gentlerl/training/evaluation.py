"""Evaluation rollouts without exploration noise (and, for diagnostics, with it)."""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.envs import EnvBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys


def _split_episodes(rollout: TensorDictBase) -> list[TensorDictBase]:
    """Each row of a ``[B, T]`` rollout up to and including its first ``done`` (all ``T`` steps
    where it has none: the episode was cut by ``max_steps``)."""
    done = rollout.get(("next", keys.DONE)).reshape(*rollout.shape).int()
    length = ((done.cumsum(-1) - done) == 0).sum(-1)  # steps before and at the first done
    return [rollout[b, : int(length[b])] for b in range(rollout.shape[0])]


@torch.no_grad()
def rollout_episodes(
    env: EnvBase,
    policy: TensorDictModule,
    episodes: int,
    max_steps: int,
    exploration: ExplorationType = ExplorationType.DETERMINISTIC,
) -> list[TensorDictBase]:
    """``episodes`` episodes of ``policy``, each a ``[T_i]`` tensordict ending at its first
    ``done`` (or after ``max_steps`` steps).

    A batched env (batch size ``[N]``) runs ``N`` episodes at a time, each hand until its first
    ``done`` (TorchRL's ``break_when_all_done``); a single env runs them one after the other.
    ``exploration``: TorchRL's exploration type while acting (``RANDOM`` lets an exploration
    policy add its noise).
    """
    out: list[TensorDictBase] = []
    with set_exploration_type(exploration):
        while len(out) < episodes:
            if env.batch_size:
                rollout = env.rollout(
                    max_steps, policy, break_when_any_done=False, break_when_all_done=True
                )
                out += _split_episodes(rollout.reshape(-1, rollout.shape[-1]))
            else:
                rollout = env.rollout(max_steps, policy, break_when_any_done=True)
                out += _split_episodes(rollout.unsqueeze(0))
    return out[:episodes]


def _any(nxt: TensorDictBase, key: str) -> float:
    """1.0 / 0.0 whether ``key`` was set at some step; NaN where the env does not write it."""
    value = nxt.get(key, None)
    return math.nan if value is None else float(value.any())


def episode_stats(episode: TensorDictBase) -> dict[str, float]:
    """``success``, ``broken`` (0/1; NaN where the env has no such outcome), ``max_impact`` (N,
    eq. 1) and the task ``return`` of one ``[T]`` episode of :func:`rollout_episodes` (the env
    must write ``impact``)."""
    nxt = episode.get("next")
    return {
        "success": _any(nxt, keys.SUCCESS),
        "broken": _any(nxt, keys.BROKEN),
        "max_impact": float(nxt.get(keys.IMPACT).max()),
        "return": float(nxt.get(keys.REWARD).sum()),
    }


def summarize_episodes(
    episodes: list[TensorDictBase],
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """The summary (``success_rate``, ``broken_rate``, ``max_impact_mean``, ``return``) and the
    :func:`episode_stats` of each of ``episodes``."""
    per_episode = [episode_stats(e) for e in episodes]
    n = max(len(per_episode), 1)
    summary = {
        "success_rate": sum(e["success"] for e in per_episode) / n,
        "broken_rate": sum(e["broken"] for e in per_episode) / n,
        "max_impact_mean": sum(e["max_impact"] for e in per_episode) / n,
        "return": sum(e["return"] for e in per_episode) / n,
    }
    return summary, per_episode


def evaluate(
    env: EnvBase, actor: TensorDictModule, episodes: int, max_steps: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run ``episodes`` deterministic episodes; ``env`` must write ``impact`` (``ImpactPenalty``).

    Returns the summary (``success_rate``, ``broken_rate``, ``max_impact_mean``, ``return``) and
    one dict per episode (``success``, ``broken``, ``max_impact`` in N, ``return``); see
    :func:`rollout_episodes` for how a batched env runs them.
    """
    return summarize_episodes(rollout_episodes(env, actor, episodes, max_steps))


def check_policy_fits(env: EnvBase, actor: TensorDictModule, policy: str) -> None:
    """Refuse (``ValueError``, one line naming the ``policy`` file and both sizes) an actor whose
    input is not the size of ``env``'s observation or whose output is not its action's."""
    layers = [m for m in actor.modules() if isinstance(m, torch.nn.Linear)]
    sizes = {"obs_dim": layers[0].in_features, "action_dim": layers[-1].out_features}
    specs = {"obs_dim": env.observation_spec[keys.OBSERVATION], "action_dim": env.action_spec}
    for name, spec in specs.items():
        if spec.shape[-1] != sizes[name]:
            raise ValueError(
                f"{policy}: its actor has {name}={sizes[name]}, but this env's "
                f"{name.removesuffix('_dim').replace('obs', 'observation')} has "
                f"{spec.shape[-1]} values (the policy trained on another env or task)"
            )


def rank(result: dict[str, float]) -> tuple[float, float, float]:
    """Order of evaluations: higher success rate, then lower broken rate, then lower mean max
    impact (the gentler of two equally successful policies). An env without success (NaN
    rates) is judged by its return: higher return, then lower mean max impact."""
    if math.isnan(result["success_rate"]):
        broken = result["broken_rate"]
        return (
            result["return"],
            0.0 if math.isnan(broken) else -broken,
            -result["max_impact_mean"],
        )
    return (result["success_rate"], -result["broken_rate"], -result["max_impact_mean"])
