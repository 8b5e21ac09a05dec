"""How hard an env's contacts are, and the force unit the tolerance rule gives it:
``gentlerl forces ENV [--episodes N] [--policy CHECKPOINT]``.

``ENV`` is a hand task (``touch``, ``fragile``, ...) or an external env
(``dm_control:finger-spin``, ``dm_control:walker-walk``, ``gym:Hopper-v5``; ``--group
feet=left_foot,right_foot`` names the contact force sites of an env read through MuJoCo's
contacts). Under uniform random actions (or a saved policy's noise-free actor)
it prints, in the env's own newtons: the share of steps with contact, the per-step impact
(paper eq. 1, the largest over the sensor sites) over contact steps, the per-episode max impact
and the per-episode impact penalty (eq. 4, lambda = [2, 2]), as quantiles; then the
``env.force_scale`` that the force-tolerance rule (:func:`tolerance_force_scale`) implies, and the penalty per episode once the force is read in that unit.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from functools import partial

import numpy as np
import torch

from gentlerl import keys
from gentlerl.apps.parsing import command_parser
from gentlerl.envs import TASKS
from gentlerl.envs.external import FORCE  # where an external env's force lands; the hand: touch

#: The hand task whose random-action contacts define the unit the paper's lambda is in.
REFERENCE_TASK = "touch"
#: The impact penalty's lambda (eq. 4) the printed penalties use: the paper's.
PAPER_LAM = (2.0, 2.0)


def force_profile(
    episodes: Sequence, lam: tuple[float, float] = PAPER_LAM, force_scale: float = 1.0
) -> dict[str, float]:
    """Contact statistics of rollout ``episodes`` (each a ``[T]`` tensordict whose ``next``
    holds ``impact`` ``[T, n_sites]`` in N, as :class:`~gentlerl.transforms.ImpactPenalty`
    writes it).

    A step has contact when its largest impact is above 0 or the force after it is (where the
    episode holds the force: ``next`` ``force`` or ``touch``). Returns ``steps``, ``episodes``,
    ``contact_share``, ``touching_share`` (episodes with any contact), the median / p90 / p99 of
    the per-step largest impact over contact steps (``step_impact_*``), the median / p90 of the
    per-episode max impact over all episodes (``episode_max_*``) and over touching episodes
    only (``touching_max_median``: the rule's statistic), and the median per-episode penalty
    (eq. 4 at ``lam`` on the impacts times ``force_scale``, ``episode_penalty_median``).
    """
    from gentlerl.functional import impact_penalty

    if not episodes:
        raise ValueError("need at least one episode, got none")
    step_max, contact, ep_max, ep_pen, touching = [], [], [], [], []
    for episode in episodes:
        nxt = episode.get("next")
        impact = nxt.get(keys.IMPACT).reshape(nxt.batch_size[0], -1).double()
        hit = impact.amax(-1) > 0
        for key in (FORCE, keys.TOUCH):
            if key in nxt.keys():
                force = nxt.get(key).reshape(nxt.batch_size[0], -1)
                hit = hit | (force.amax(-1) > 0)
                break
        step_max.append(impact.amax(-1))
        contact.append(hit)
        ep_max.append(float(impact.max()))
        ep_pen.append(float(impact_penalty(impact * force_scale, *lam).sum()))
        touching.append(bool(hit.any()))
    steps, hits = torch.cat(step_max), torch.cat(contact)
    on = steps[hits].numpy() if hits.any() else np.zeros(1)
    ep_max_a = np.array(ep_max)
    touching_a = np.array(touching)
    return {
        "steps": int(steps.numel()),
        "episodes": len(episodes),
        "contact_share": float(hits.double().mean()),
        "touching_share": float(touching_a.mean()),
        "step_impact_median": float(np.median(on)),
        "step_impact_p90": float(np.percentile(on, 90)),
        "step_impact_p99": float(np.percentile(on, 99)),
        "episode_max_median": float(np.median(ep_max_a)),
        "episode_max_p90": float(np.percentile(ep_max_a, 90)),
        "touching_max_median": float(np.median(ep_max_a[touching_a])) if touching_a.any() else 0.0,
        "episode_penalty_median": float(np.median(ep_pen)),
    }


def tolerance_force_scale(env_impact: float, reference_impact: float) -> float:
    r"""The force-tolerance rule: :math:`s = q_\text{hand} / q_\text{env}`.

    ``q`` is the median, over the random-action episodes that touch, of the episode's largest
    impact (N): "a random policy's typical worst hit on this env costs what it costs on the
    hand", so the paper's lambda (eq. 3-4, the impact "that is acceptable", in the hand's
    fingertip newtons) and lambda' (eq. 8, in penalty units) keep their meaning. ``s`` is
    ``env.force_scale``: impacts and penalties are computed on the force times ``s``.
    """
    for name, value in (("env_impact", env_impact), ("reference_impact", reference_impact)):
        if not (isinstance(value, int | float) and 0 < value < float("inf")):
            raise ValueError(
                f"{name} must be a finite impact > 0 N (random actions never touched?), "
                f"got {value!r}"
            )
    return float(reference_impact) / float(env_impact)


def measure(
    env_name: str,
    episodes: int,
    seed: int = 0,
    policy: str | None = None,
    force_groups: dict[str, list[str]] | None = None,
) -> list:
    """``episodes`` rollouts (``[T]`` tensordicts with ``impact`` in N) on ``env_name``: random
    actions, or the noise-free actor of the checkpoint ``policy`` (its run's env, in newtons).
    ``force_groups``: an external env's contact force sites (the ``contacts`` adapter's groups,
    :func:`~gentlerl.envs.contacts.resolve_groups`), random actions only."""
    from gentlerl.training.builders import default_env_factory
    from gentlerl.training.evaluation import (
        MAX_EPISODE_STEPS,
        check_episodes,
        check_policy_fits,
        make_eval_env,
        rollout_episodes,
    )

    check_episodes(episodes)
    if force_groups is not None and (policy is not None or env_name in TASKS):
        raise ValueError(
            "--group names the contact force sites of an external env under random actions; a "
            "hand task reads its touch sensors, a policy its run's env.force_groups"
        )
    actor = None
    if policy is not None:
        from gentlerl.training.checkpoint import load_checkpoint, policy_from_state

        cfg, actor = policy_from_state(load_checkpoint(policy), policy)
        trained = cfg.env.name or cfg.task
        if env_name != trained:  # the numbers would be printed under a name they are not of
            raise ValueError(
                f"{policy} acts on {trained!r} (the env it trained on); ENV is {env_name!r}: "
                f"measure it as `gentlerl forces {trained} --policy {policy}`"
            )
        cfg = replace(cfg, env=replace(cfg.env, force_scale=1.0), seed=seed)
        force_key = cfg.env.force if cfg.env.name is not None else keys.TOUCH
        factory = default_env_factory(cfg)
    elif env_name in TASKS:
        from gentlerl.envs import make_env

        factory, force_key = partial(make_env, env_name, seed=seed), keys.TOUCH
    else:
        from gentlerl.envs.external import check_name, make_external_env

        problems = check_name(env_name)
        if problems:
            raise ValueError(f"ENV {env_name!r}: {problems[0]} (or a hand task: {list(TASKS)})")
        factory = partial(make_external_env, env_name, seed=seed, force_groups=force_groups)
        force_key = FORCE
    env = make_eval_env(factory, seed, force_key=force_key)
    torch.manual_seed(seed)
    try:
        if actor is not None:
            check_policy_fits(env, actor, str(policy))
        return rollout_episodes(env, actor, episodes, max_steps=MAX_EPISODE_STEPS)
    finally:
        env.close()


def _row(name: str, p: dict[str, float]) -> str:
    return (
        f"{name:<26} {p['contact_share']:>7.1%} {p['step_impact_median']:>8.2f} "
        f"{p['step_impact_p90']:>8.2f} {p['episode_max_median']:>8.2f} "
        f"{p['episode_max_p90']:>8.2f} {p['touching_max_median']:>8.2f} "
        f"{p['episode_penalty_median']:>10.1f}"
    )


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl forces") -> dict[str, float]:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument(
        "env", help="a hand task or an external env (dm_control:DOMAIN-TASK, gym:ID)"
    )
    parser.add_argument(
        "--group",
        action="append",
        metavar="NAME=BODY[,BODY...]",
        help="an external env's contact force site: the bodies (geom:NAME, subtree:NAME) whose "
        "contact forces it sums; repeat for several (default: the env's, e.g. walker's feet)",
    )
    parser.add_argument("--episodes", type=int, default=20, help="episodes to measure")
    parser.add_argument("--seed", type=int, default=0, help="seed of the env and the actions")
    parser.add_argument("--policy", help="a checkpoint whose actor acts instead of random actions")
    parser.add_argument(
        "--reference-impact",
        type=float,
        help=f"the rule's hand statistic (N); None: measured on {REFERENCE_TASK!r} here",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    groups = None
    if args.group:
        groups = {}
        for item in args.group:
            name, _, bodies = item.partition("=")
            if not name or not bodies:
                parser.error(f"--group {item!r} must read NAME=BODY[,BODY...]")
            groups[name] = bodies.split(",")
    rollouts = measure(args.env, args.episodes, args.seed, args.policy, groups)
    profile = force_profile(rollouts)
    reference = args.reference_impact
    if reference is None:
        hand = measure(REFERENCE_TASK, args.episodes, args.seed)
        reference = force_profile(hand)["touching_max_median"]
    scale = tolerance_force_scale(profile["touching_max_median"], reference)
    scaled = force_profile(rollouts, force_scale=scale)
    result = {
        "env": args.env,
        **profile,
        "reference_impact": reference,
        "force_scale": scale,
        "scaled_penalty_median": scaled["episode_penalty_median"],
    }
    if args.json:
        print(json.dumps(result))
        return result
    source = "random actions" if args.policy is None else args.policy
    print(f"{args.env}: {profile['episodes']} episodes, {profile['steps']} steps, {source}, N")
    if args.policy is None and args.env not in TASKS:
        from gentlerl.envs.contacts import default_groups

        sites = groups or default_groups(args.env)
        if sites is not None:
            print(
                "sites (MuJoCo contacts): "
                + "; ".join(f"{k}={','.join(v)}" for k, v in sites.items())
            )
    print(
        f"{'':<26} {'contact':>7} {'step m50':>8} {'step m90':>8} {'ep max50':>8} "
        f"{'ep max90':>8} {'touch50':>8} {'r^f / ep':>10}"
    )
    print(_row("as read (N)", profile))
    print(
        f"rule: force_scale = {reference:.3g} N ({REFERENCE_TASK}) / "
        f"{profile['touching_max_median']:.3g} N = {scale:.4g}  ->  env.force_scale={scale:.3g}"
    )
    print(f"r^f per episode in that unit (median): {scaled['episode_penalty_median']:.1f}")
    return result
