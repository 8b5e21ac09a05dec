"""Evaluation rollouts without exploration noise (and, for diagnostics, with it).

:func:`evaluate_actor` is the public call: any TorchRL actor, on an env factory's env with the
impact written (paper eq. 1), over held-out episodes, summarised as ``gentlerl evaluate`` prints
it (success and broken rates, median / p90 max impact in the env's force unit).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.functional import excess_cost
from gentlerl.transforms import ImpactPenalty

#: A run's evaluation env is seeded with the run's seed plus this (apart from every worker's).
EVAL_SEED_OFFSET = 10_000

#: The most episodes a command rolls out (``gentlerl evaluate`` / ``forces``: ~1 hour at 200
#: steps each), and the most steps of one of its episodes (the env's time limit ends them first).
MAX_EPISODES, MAX_EPISODE_STEPS = 10_000, 100_000


def check_episodes(episodes: object, most: int = MAX_EPISODES) -> int:
    """``episodes`` if it is an integer in ``[1, most]``, else a one-line ``ValueError``."""
    if isinstance(episodes, bool) or not isinstance(episodes, int) or not 1 <= episodes <= most:
        raise ValueError(f"episodes must be an integer in [1, {most:,}], got {episodes!r}")
    return episodes


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


#: The episode outcomes an env may define (the hand's tasks do; an external env may not).
OUTCOMES = (keys.SUCCESS, keys.BROKEN)


def episode_stats(episode: TensorDictBase, tolerance: float | None = None) -> dict[str, float]:
    """``success`` and ``broken`` (1.0 / 0.0 whether set at some step; left out where the env
    does not write them), ``max_impact`` (N, eq. 1) and the task ``return`` of one ``[T]``
    episode of :func:`rollout_episodes` (the env must write ``impact``); with a ``tolerance``
    (N) also its safe-RL ``cost``, the sum over its steps of
    :func:`~gentlerl.functional.excess_cost` (steps of violation)."""
    nxt = episode.get("next")
    outcomes = {key: float(nxt.get(key).any()) for key in OUTCOMES if key in nxt.keys()}
    impact = nxt.get(keys.IMPACT)
    stats = {**outcomes, "max_impact": float(impact.max())}
    stats["return"] = float(nxt.get(keys.REWARD).sum())
    if tolerance is not None:  # [T, sites]: each step's cost, summed over the episode
        stats["cost"] = float(excess_cost(impact.reshape(len(nxt), -1), tolerance).sum())
    return stats


def summarize_episodes(
    episodes: list[TensorDictBase], tolerance: float | None = None
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """The summary (``success_rate`` and ``broken_rate`` where the env defines them,
    ``max_impact_mean``, ``return``, and with a ``tolerance`` the mean ``cost``) and the
    :func:`episode_stats` of each of ``episodes``."""
    per_episode = [episode_stats(e, tolerance) for e in episodes]
    n = max(len(per_episode), 1)
    defined = [k for k in OUTCOMES if per_episode and all(k in e for e in per_episode)]
    summary = {f"{k}_rate": sum(e[k] for e in per_episode) / n for k in defined}
    summary["max_impact_mean"] = sum(e["max_impact"] for e in per_episode) / n
    summary["return"] = sum(e["return"] for e in per_episode) / n
    if tolerance is not None:
        summary["cost"] = sum(e["cost"] for e in per_episode) / n
    return summary, per_episode


def evaluate(
    env: EnvBase, actor: TensorDictModule, episodes: int, max_steps: int
) -> tuple[dict[str, float], list[dict[str, float]]]:
    """Run ``episodes`` deterministic episodes; ``env`` must write ``impact`` (``ImpactPenalty``).

    Returns the summary and one dict per episode of :func:`summarize_episodes` (``success``,
    ``broken`` where the env defines them, ``max_impact`` in N, ``return``); see
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
    impact (the gentler of two equally successful policies). An env without success (no rate;
    NaN in the evaluations of runs saved before) is judged by its return: higher return, then
    lower broken rate where it has one, then lower mean max impact."""
    success = result.get("success_rate", math.nan)
    broken = result.get("broken_rate", math.nan)
    broken = 0.0 if math.isnan(broken) else broken
    if math.isnan(success):
        return (result["return"], -broken, -result["max_impact_mean"])
    return (success, -broken, -result["max_impact_mean"])


def takes_num_envs(env_factory: Callable[..., Any]) -> bool:
    """Whether ``env_factory`` builds batched envs (it takes ``num_envs``, as ``make_env``)."""
    try:
        params = inspect.signature(env_factory).parameters.values()
    except (TypeError, ValueError):  # builtins / C callables: no signature to read
        return False
    return any(p.name == "num_envs" for p in params)


def make_eval_env(
    env_factory: Callable[..., EnvBase], seed: int, episodes: int = 1, force_key: str = keys.TOUCH
) -> EnvBase:
    """The evaluation env (writes ``impact`` from ``force_key``): ``episodes`` hands stepped
    together where the factory builds batched envs (all episodes of an evaluation in one
    rollout), else one."""
    batched = episodes > 1 and takes_num_envs(env_factory)
    env = TransformedEnv(
        env_factory(num_envs=episodes) if batched else env_factory(),
        ImpactPenalty(in_keys=[force_key]),
    )
    env.set_seed(seed)
    return env


def summarize(episodes: Sequence[dict[str, float]]) -> dict[str, float]:
    """Success and broken rates and median / p90 max impact (N) of evaluation episodes.

    ``episodes``: one dict per episode with ``success``, ``broken`` (0/1; an env without them
    has no rates), ``max_impact`` and ``return`` (``mean_return``), as :func:`evaluate` returns
    them.
    """
    if not episodes:
        raise ValueError("need at least one episode to summarize, got none")
    impact = np.array([e["max_impact"] for e in episodes], dtype=np.float64)
    rates = {
        f"{k}_rate": float(np.mean([e[k] for e in episodes]))
        for k in ("success", "broken")
        if all(k in e for e in episodes)
    }
    return {
        "episodes": len(episodes),
        **rates,
        "median_max_impact": float(np.median(impact)),
        "p90_max_impact": float(np.percentile(impact, 90)),
        "mean_return": float(np.mean([e.get("return", np.nan) for e in episodes])),
    }


def actor_episodes(
    env_factory: Callable[..., EnvBase],
    actor: TensorDictModule,
    episodes: int,
    seed: int = 0,
    *,
    force_key: str = keys.TOUCH,
) -> list[dict[str, float]]:
    """``episodes`` deterministic episodes of ``actor`` on ``env_factory()``'s env, seeded with
    ``seed``: one :func:`episode_stats` dict each (``max_impact`` in N, ``return``, ``success``
    where the env defines it). Torch's global random state is left as it was (an evaluation in
    the middle of training does not reseed it). Any TorchRL actor that reads the env's
    observation works (a SAC ``ProbabilisticActor`` acts with its mode)."""
    check_episodes(episodes)
    env = make_eval_env(env_factory, seed, episodes, force_key)
    try:
        with torch.random.fork_rng():  # the caller's random stream goes on as if not evaluated
            torch.manual_seed(seed)
            return evaluate(env, actor, episodes, max_steps=MAX_EPISODE_STEPS)[1]
    finally:
        env.close()


def evaluate_actor(
    env_factory: Callable[..., EnvBase],
    actor: TensorDictModule,
    episodes: int,
    seed: int = 0,
    *,
    force_key: str = keys.TOUCH,
) -> dict[str, float]:
    """:func:`actor_episodes` summarised, as ``gentlerl evaluate --episodes N --seed S``
    measures a saved policy: :func:`summarize`'s numbers and ``median_max_impact_successful``
    (NaN when no episode succeeded). The same ``seed`` gives the same episodes."""
    per_episode = actor_episodes(env_factory, actor, episodes, seed, force_key=force_key)
    successful = [e["max_impact"] for e in per_episode if e.get("success") == 1.0]
    summary = summarize(per_episode)
    summary["median_max_impact_successful"] = (
        float(np.median(successful)) if successful else float("nan")
    )
    return summary
