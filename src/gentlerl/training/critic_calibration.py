r"""Critic calibration: each head's predicted Q against the return its reward really earns.

Along rollouts of an actor, head :math:`k` of the multi-head D4PG critic predicts
:math:`\hat Q^k_t = \mathbb{E}[Z^k(s_t, a_t)]` at the action :math:`a_t` taken; the realised
return of that head from step :math:`t` on is the discounted sum of its reward component (computed
by the run's own reward transforms, with their current models), bootstrapped where the episode is
cut as the learner bootstraps it (:class:`~gentlerl.objectives.MultiHeadD4PGLoss`): with the
critic's own :math:`\hat Q^k(s', \pi(s'))` at the last next-state after a truncation (time limit),
and after a termination too for the heads that are not episodic; an episodic head's return stops
at termination. The bootstrap reads the online critic and actor (the learner's target copies
lag them by at most ``learner.target_update_period`` updates). A calibrated critic has :math:`\hat Q \approx G` on average (its bias near 0) and
its realised returns inside the head's support :math:`[v_{min}, v_{max}]`.

Used by the ``gentlerl calibration`` command (:mod:`gentlerl.apps.calibration`) and, on the
deterministic evaluation episodes, by the training loop (``calibration/<head>/...`` scalars;
``surprise_sources/...``: :func:`penalty_surprise_sources`).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from torchrl.envs.transforms import Compose, Transform

from gentlerl import keys
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.transforms import PenaltySurprise
from gentlerl.transforms.surprise import frozen_scale


def expected_value(logits: torch.Tensor, atoms: torch.Tensor) -> torch.Tensor:
    r"""Expected value of categorical distributions: :math:`Q = \sum_j \mathrm{softmax}(l)_j z_j`.

    Args:
        logits, atoms: ``[..., num_atoms]`` (e.g. the critic's ``[..., K, num_atoms]``).

    Returns ``[...]``. Example: logits ``[0, 0]`` on atoms ``[-1, 3]`` -> 1.0.
    """
    if logits.shape[-1] != atoms.shape[-1]:
        raise ValueError(f"logits {tuple(logits.shape)} and atoms {tuple(atoms.shape)} differ")
    return (logits.softmax(-1) * atoms).sum(-1)


def discounted_returns(
    rewards: torch.Tensor,
    done: torch.Tensor,
    bootstrap: torch.Tensor,
    gamma: float,
    cut: torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Realised discounted returns of consecutive episodes laid end to end along the last dim.

    .. math::
        G_t = r_t + \gamma \left[(1 - d_t)\, G_{t+1} + d_t (1 - c_t)\, B_t\right],
        \qquad d_{T-1} := 1,

    where :math:`d_t` says that the episode ends after step :math:`t`, :math:`c_t` that its
    bootstrap is cut there (an episodic head's termination) and :math:`B_t` is the value of the
    next state :math:`s_{t+1}` (read only where :math:`d_t`). The last step always ends a segment:
    a rollout cut by a step limit is bootstrapped like a truncation.

    Args:
        rewards: ``[..., T]``.
        done, cut: ``[..., T]`` bool (``cut`` defaults to no termination: always bootstrap).
        bootstrap: ``[..., T]``.
        gamma: discount per step, in [0, 1].

    Example: rewards ``[1, 1, 1]``, done only at the end, gamma 0.5, bootstrap 4 ->
    ``[1.75 + 0.5, 1.5 + 1, 1 + 2] = [2.25, 2.5, 3.0]``; cut there -> ``[1.75, 1.5, 1.0]``.
    """
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma}")
    if rewards.shape[-1] == 0:
        return rewards.clone()
    done = done.bool().expand_as(rewards).clone()
    done[..., -1] = True
    cut = torch.zeros_like(done) if cut is None else cut.bool().expand_as(rewards)
    tail = bootstrap * (~cut).to(rewards.dtype)
    returns = torch.empty_like(rewards)
    following = torch.zeros_like(rewards[..., 0])
    for t in range(rewards.shape[-1] - 1, -1, -1):
        following = torch.where(done[..., t], tail[..., t], following)
        following = rewards[..., t] + gamma * following
        returns[..., t] = following
    return returns


def calibration_stats(
    predicted: torch.Tensor,
    realised: torch.Tensor,
    v_min: float,
    v_max: float,
    eps: float = 0.1,
) -> dict[str, float]:
    r"""How well ``predicted`` values match ``realised`` returns (both ``[N]``, one head).

    ``predicted``, ``realised``: their means; ``bias`` = predicted - realised;
    ``mae`` = :math:`\overline{|\hat Q - G|}`; ``rel_error`` = :math:`|\mathrm{bias}| /
    \max(|\overline{G}|, \epsilon)` (issue 21's "within 30 %" target reads it; ``eps`` = 0.1, a
    tenth of the task's +1, keeps a return near 0 from making it explode); ``outside_support``:
    the fraction of realised returns outside the head's support ``[v_min, v_max]``, which the
    critic cannot represent. Example: predicted ``[0, 0]``, realised ``[-4, -16]`` on [-10, 0] ->
    bias 10, rel_error 1.0, outside_support 0.5.
    """
    if predicted.shape != realised.shape or predicted.ndim != 1 or predicted.numel() == 0:
        raise ValueError(
            f"predicted and realised must be equal non-empty [N], got {tuple(predicted.shape)} "
            f"and {tuple(realised.shape)}"
        )
    p, g = predicted.double(), realised.double()
    bias = float(p.mean() - g.mean())
    return {
        "predicted": float(p.mean()),
        "realised": float(g.mean()),
        "bias": bias,
        "mae": float((p - g).abs().mean()),
        "rel_error": abs(bias) / max(abs(float(g.mean())), eps),
        "outside_support": float(((g < v_min) | (g > v_max)).double().mean()),
    }


@torch.no_grad()
def critic_values(
    loss: MultiHeadD4PGLoss, td: TensorDictBase, act: bool = False
) -> tuple[torch.Tensor, torch.Tensor]:
    """``([N, K] expected values, [K, num_atoms] atoms)`` of the online critic on ``td``'s
    ``observation`` and ``action`` (with ``act``: the online actor's action, no noise), on the
    CPU wherever the loss is."""
    device = next(loss.parameters()).device
    td = td.select(*loss.actor_in_keys, *loss.value_in_keys, strict=False).to(device)
    if act:
        td = loss.actor_network(td)
    with loss.value_network_params.to_module(loss.value_network):
        out = loss.value_network(td)
    logits = out.get(loss.tensor_keys.value_logits)
    atoms = out.get(loss.tensor_keys.value_atoms)
    values, atoms = expected_value(logits, atoms), atoms.reshape(-1, *atoms.shape[-2:])[0]
    return values.cpu(), atoms.cpu()


@torch.no_grad()
def measure_calibration(
    loss: MultiHeadD4PGLoss,
    transform: Transform,
    episodes: Sequence[TensorDictBase],
    gamma: float,
    eps: float = 0.1,
) -> dict[str, dict[str, dict[str, float]]]:
    """Per head, :func:`calibration_stats` over every step and over the episodes' first steps.

    Args:
        loss: the run's D4PG loss (online critic and actor, ``episodic`` flags, reward keys).
        transform: writes the reward components under ``"next"`` (the run's
            :class:`~gentlerl.rewards.IntrinsicRewards` ``transform``, models and gate as they are).
        episodes: ``[T_i]`` rollouts ending at their first ``done`` or cut by a step limit (as
            :func:`~gentlerl.training.evaluation.rollout_episodes` returns them); not modified.
        gamma: the learner's discount.

    Returns ``{head: {"all": stats, "start": stats}}``: :func:`calibration_stats` and
    ``bootstrap``, the mean part of the realised return that is the critic's own value at the
    episodes' last next-states (discounted): where it dominates (short episodes of a
    non-episodic head), the comparison checks self-consistency more than ground truth.
    """
    if not episodes:
        raise ValueError("need at least one episode to measure calibration, got none")
    lengths = torch.tensor([e.shape[0] for e in episodes])
    steps = _rewarded_steps(transform, episodes)
    ends = lengths.cumsum(0) - 1
    done = torch.zeros(steps.shape[0], dtype=torch.bool)
    done[ends] = True
    heads = loss.reward_keys
    rewards = torch.stack([steps.get(("next", k)).reshape(-1) for k in heads])  # [K, N]
    predicted, atoms = critic_values(loss, steps)
    bootstrap = torch.zeros_like(rewards)
    bootstrap[:, ends] = critic_values(loss, steps[ends].get("next"), act=True)[0].T
    terminated = steps.get(("next", keys.TERMINATED)).reshape(-1).bool()
    cut = terminated & loss.episodic.reshape(-1, 1).cpu()  # [K, N]: non-episodic heads bootstrap
    realised = discounted_returns(rewards, done, bootstrap, gamma, cut)
    # The part of G_t that is the critic's own bootstrap: the returns of zero rewards.
    borrowed = discounted_returns(torch.zeros_like(rewards), done, bootstrap, gamma, cut)
    start = torch.cat([ends.new_zeros(1), ends[:-1] + 1])
    report = {}
    for k, head in enumerate(heads):
        name = head if isinstance(head, str) else "_".join(head)
        v_min, v_max = float(atoms[k, 0]), float(atoms[k, -1])
        p, g, b = predicted[:, k], realised[k], borrowed[k].double()
        report[name] = {
            "all": calibration_stats(p, g, v_min, v_max, eps) | {"bootstrap": float(b.mean())},
            "start": calibration_stats(p[start], g[start], v_min, v_max, eps)
            | {"bootstrap": float(b[start].mean())},
        }
    return report


def _rewarded_steps(transform: Transform, episodes: Sequence[TensorDictBase]) -> TensorDictBase:
    """The episodes' steps end to end (without the touch grids), with ``transform``'s rewards
    (scored with the curiosity's running scale as it is: :func:`frozen_scale`)."""
    members = transform if isinstance(transform, Compose) else [transform]
    with frozen_scale(members):
        return transform(
            torch.cat([e.exclude(keys.TOUCH_GRID, ("next", keys.TOUCH_GRID)) for e in episodes], 0)
        )


def penalty_surprise_sources(
    transform: Transform, episodes: Sequence[TensorDictBase]
) -> dict[str, float | int | None] | None:
    r"""Where the penalty surprise of the episodes' contact steps (:math:`r^f < 0`) comes from.

    Means over those steps of :meth:`~gentlerl.transforms.PenaltySurprise.sources` under the
    run's transforms and today's target model (``transform``, as in
    :func:`measure_calibration`), plus ``r_sp`` as that model scores them (gate and scale
    included; a run with ``rescore_surprise=false`` was paid the values of older models),
    ``nll`` = ``spread`` + ``error`` (unfloored), ``z2`` = 2 x ``error`` (the squared z-score),
    ``penalty_std``, ``contact_steps`` and ``steps``. ``z2_all_steps`` and ``spread_all_steps``
    average over every step, contact or not, as the model is trained: there a calibrated model
    has ``z2`` ~1 (below: too wide; above: too sure); over contact steps alone, selected by
    their outcome, the tail pushes ``z2`` up. ``None`` when ``transform`` has no penalty
    surprise; a mean over no step is ``None``.
    """
    members = transform if isinstance(transform, Compose) else [transform]
    found = [t for t in members if isinstance(t, PenaltySurprise)]
    if not found:
        return None
    surprise = found[0]
    steps = _rewarded_steps(transform, episodes)
    device = getattr(transform, "models_device", None) or steps.device
    parts = {k: v.cpu() for k, v in surprise.sources(steps.to(device)).items()}
    contact = parts["penalty"] < 0
    parts |= {
        "r_sp": steps.get(("next", surprise.out_keys[0])),
        "nll": parts["spread"] + parts["error"],
        "z2": 2 * parts["error"],
    }
    stats: dict[str, float | int | None] = {
        name: _mean(value[contact]) for name, value in parts.items()
    }
    return stats | {
        "z2_all_steps": _mean(parts["z2"]),
        "spread_all_steps": _mean(parts["spread"]),
        "penalty_std": float(parts["penalty"][contact].std()) if contact.sum() > 1 else None,
        "contact_steps": int(contact.sum()),
        "steps": int(contact.numel()),
    }


def _mean(values: torch.Tensor) -> float | None:
    """The mean as a float, ``None`` for no values (JSON has no NaN)."""
    return float(values.mean()) if values.numel() else None


def calibration_scalars(report: dict[str, dict[str, dict[str, float]]]) -> dict[str, float]:
    """``calibration/<head>/{predicted,realised,bias}`` over every step of a
    :func:`measure_calibration` report, for a run's logs."""
    return {
        f"calibration/{head}/{stat}": where["all"][stat]
        for head, where in report.items()
        for stat in ("predicted", "realised", "bias")
    }


#: What :func:`evaluation_scalars` logs of :func:`penalty_surprise_sources`.
SOURCE_SCALARS = (
    "r_sp", "curiosity", "refund", "spread", "error", "z2", "z2_all_steps", "aleatoric",
    "epistemic",
)  # fmt: skip


def evaluation_scalars(
    loss: MultiHeadD4PGLoss,
    transform: Transform,
    episodes: Sequence[TensorDictBase],
    gamma: float,
) -> dict[str, float]:
    """What a run logs of its evaluation episodes: :func:`calibration_scalars` and, with penalty
    surprise and contact, ``surprise_sources/<name>`` for :data:`SOURCE_SCALARS`
    (:func:`penalty_surprise_sources`), so that a bonus that does not fade shows why over the run.
    """
    scalars = calibration_scalars(measure_calibration(loss, transform, episodes, gamma))
    sources = penalty_surprise_sources(transform, episodes)
    if sources is not None and sources["contact_steps"] > 0:
        scalars |= {f"surprise_sources/{name}": sources[name] for name in SOURCE_SCALARS}
    return scalars
