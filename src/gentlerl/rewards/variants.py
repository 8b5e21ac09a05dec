"""The reward components (one critic head each) and the paper's variants that combine them.

Adding a reward transform with its own critic head touches three places: its key in
:mod:`gentlerl.keys`, its transform in :mod:`gentlerl.transforms`, and here an entry of
:data:`COMPONENTS` (how to build it) and the :data:`VARIANTS` that use it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from gentlerl import keys
from gentlerl.config import EnvConfig, GentlenessConfig, NetworkConfig

if TYPE_CHECKING:
    from torchrl.envs.transforms import Transform
    from torchrl.objectives import HardUpdate
    from torchrl.objectives.common import LossModule

# The builders import the models, losses and transforms (torch, TorchRL) when they build: the
# tables below are read by ``--help`` and the config checks, which must not wait for them.


@dataclass
class Ingredients:
    """What a component's builder may use: the env's sizes, the gentleness settings, a seed, and
    the observation and force entries the transforms read."""

    obs_dim: int
    action_dim: int
    feature_shapes: Mapping[str, Sequence[int]]
    settings: GentlenessConfig
    seed: int
    obs_key: str = keys.OBSERVATION
    force_key: str = keys.TOUCH


@dataclass
class Part:
    """A built component: its transform and, for a learned reward, the loss training its model.

    ``target_updater``: the TorchRL ``HardUpdate`` copying the loss's target parameters, made by
    :func:`target_updater` before the transform reads them (``None``: the transform reads the
    online model).
    """

    transform: Transform
    loss: LossModule | None = None
    target_updater: HardUpdate | None = None


def target_updater(loss: LossModule, period: int) -> HardUpdate:
    """A ``HardUpdate`` of ``loss`` copying its target model, normaliser statistics included
    (:class:`~gentlerl.objectives.model_losses.ModelHardUpdate`), every ``period`` ``step()`` calls.

    Made before anything reads ``loss.target_*_params``: TorchRL warns on every read of target
    parameters that no updater has been associated with.
    """
    from gentlerl.objectives.model_losses import ModelHardUpdate

    # HardUpdate copies on the (interval + 1)-th step() call.
    return ModelHardUpdate(loss, value_network_update_interval=period - 1)


@dataclass(frozen=True)
class Component:
    """One reward component (one critic head).

    Attributes:
        build: makes its :class:`Part`; ``None`` where the env or ``ImpactPenalty`` writes it.
        upper_bound: the reward never exceeds it (0 for penalties); with
            ``network.bounded_support`` its critic's support tops there.
        dense: paid at every step (penalties, curiosity), so its return grows with the horizon;
            the task reward is paid once, when the episode ends (:func:`head_supports`).
        intrinsic: a curiosity reward: switched on after the reward delay, and its critic head
            bootstraps through termination unless ``learner.episodic_intrinsic``.
        model: the name of its model (``model_<name>`` in the logs).
    """

    build: Callable[[Ingredients], Part] | None = None
    upper_bound: float | None = None
    dense: bool = True
    intrinsic: bool = False
    model: str | None = None


def _hidden(ing: Ingredients) -> tuple[int, int, int]:
    return (ing.settings.model_hidden,) * 3


def _dynamics_surprise(ing: Ingredients) -> Part:
    from gentlerl.models import DynamicsModel
    from gentlerl.objectives import EnsembleModelLoss
    from gentlerl.transforms import DynamicsSurprise

    model = DynamicsModel(
        ing.obs_dim,
        ing.action_dim,
        dict(ing.feature_shapes),
        ing.settings.ensemble_size,
        _hidden(ing),
        seed=ing.seed,
        obs_key=ing.obs_key,
    )
    loss = EnsembleModelLoss(model, name="dynamics")
    updater = target_updater(loss, ing.settings.dynamics_target_period)
    scale = ing.settings.surprise_scale * ing.settings.dynamics_surprise_scale
    transform = DynamicsSurprise(model, loss.target_model_params, scale=scale)
    return Part(transform, loss, updater)


def _penalty_surprise(ing: Ingredients) -> Part:
    from gentlerl.models import PenaltyModel
    from gentlerl.objectives import EnsembleModelLoss
    from gentlerl.transforms import PenaltySurprise

    s = ing.settings
    model = PenaltyModel(
        ing.obs_dim,
        ing.action_dim,
        s.ensemble_size,
        _hidden(ing),
        seed=ing.seed + 1,
        obs_key=ing.obs_key,
    )
    loss = EnsembleModelLoss(model, name="penalty")
    updater = target_updater(loss, s.penalty_target_period)
    transform = PenaltySurprise(
        model,
        loss.target_model_params,
        lam_prime=s.lam_prime,
        scale=s.surprise_scale,
        nll_floor=s.surprise_nll_floor,
        kind=s.surprise_kind,
        normalize=s.curiosity_norm,
    )
    return Part(transform, loss, updater)


def _icm_reward(ing: Ingredients) -> Part:
    import torch

    from gentlerl.models import ICMModel
    from gentlerl.objectives import ICMLoss
    from gentlerl.transforms import ICMReward

    with torch.random.fork_rng():
        torch.manual_seed(ing.seed + 2)
        model = ICMModel(ing.obs_dim, ing.action_dim, obs_key=ing.obs_key)
    loss = ICMLoss(model)
    return Part(ICMReward(model, loss.model_params, eta=ing.settings.icm_eta), loss)


def _force_penalty(ing: Ingredients) -> Part:
    from gentlerl.transforms import ForcePenalty

    return Part(ForcePenalty(in_keys=[ing.force_key]))


def _excess_penalty(ing: Ingredients) -> Part:
    from gentlerl.transforms import ExcessPenalty

    # Without a tolerance, the impact the paper's acceptability puts at 1/2 (lambda_2, N).
    s = ing.settings
    return Part(ExcessPenalty(s.lam[1] if s.tolerance is None else s.tolerance))


def _torque_penalty(ing: Ingredients) -> Part:
    from gentlerl.transforms import TorquePenalty

    return Part(TorquePenalty())


#: Every reward component, by its key (= the name of its critic head).
COMPONENTS: dict[str, Component] = {
    keys.REWARD: Component(dense=False),  # the tasks pay once, at success or break
    keys.PENALTY: Component(upper_bound=0.0),  # eq. 4: never positive; ImpactPenalty writes it
    keys.DYNAMICS_SURPRISE: Component(_dynamics_surprise, intrinsic=True, model="dynamics"),
    keys.PENALTY_SURPRISE: Component(_penalty_surprise, intrinsic=True, model="penalty"),
    keys.ICM_REWARD: Component(_icm_reward, intrinsic=True, model="icm"),
    # Beyond the paper (its future work on wear): total fingertip force and actuator effort.
    keys.FORCE_PENALTY: Component(_force_penalty, upper_bound=0.0),
    keys.TORQUE_PENALTY: Component(_torque_penalty, upper_bound=0.0),
    # Method IV: the impact above the tolerance, in tolerances, at most 1 a step (a cost head).
    keys.EXCESS_PENALTY: Component(_excess_penalty, upper_bound=0.0),
}

#: Reward components (critic heads, in order) of each variant of the paper's experiments.
VARIANTS: dict[str, tuple[str, ...]] = {
    "r": (keys.REWARD,),
    "r+rf": (keys.REWARD, keys.PENALTY),
    "r+rf+rs": (keys.REWARD, keys.PENALTY, keys.DYNAMICS_SURPRISE),
    "r+rf+rsp": (keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE),
    "r+icm": (keys.REWARD, keys.ICM_REWARD),
    "rs": (keys.DYNAMICS_SURPRISE,),
    "rf+rs": (keys.PENALTY, keys.DYNAMICS_SURPRISE),
    "rf+rsp": (keys.PENALTY, keys.PENALTY_SURPRISE),
    # The paper's method plus a wear penalty: rF total force, rt actuator effort (torque).
    "r+rf+rsp+rF": (keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE, keys.FORCE_PENALTY),
    "r+rf+rsp+rt": (keys.REWARD, keys.PENALTY, keys.PENALTY_SURPRISE, keys.TORQUE_PENALTY),
    # Method IV's constrained baseline: the task and a cost critic (gentleness.multiplier=lagrangian).
    "r+rc": (keys.REWARD, keys.EXCESS_PENALTY),
}


def reward_keys(variant: str) -> list[str]:
    """The reward components of ``variant``, in critic-head order."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; expected one of {sorted(VARIANTS)}")
    return list(VARIANTS[variant])


def intrinsic_keys(reward_keys: Sequence[str]) -> list[str]:
    """The curiosity rewards among ``reward_keys``."""
    return [k for k in reward_keys if COMPONENTS[k].intrinsic]


def discounted_horizon(gamma: float, horizon: int) -> float:
    r"""The largest discounted return of a reward bounded by 1 per step over ``horizon`` steps.

    .. math:: H_\gamma(T) = \sum_{t=0}^{T-1} \gamma^t = \frac{1 - \gamma^T}{1 - \gamma}

    (``T`` for ``gamma = 1``). Touch's 200 steps at gamma 0.99: 86.6.
    """
    if not 0.0 <= gamma <= 1.0 or horizon < 1:
        raise ValueError(f"need gamma in [0, 1] and horizon >= 1, got {gamma} and {horizon}")
    return float(horizon) if gamma == 1.0 else (1.0 - gamma**horizon) / (1.0 - gamma)


#: The support's margin on each side, as a fraction of the returns' range (:func:`derived_support`).
HEADROOM = 0.1


def derived_support(
    reward_bounds: tuple[float, float], horizon: float, headroom: float = HEADROOM
) -> tuple[float, float]:
    r"""A head's support from its reward's per-step bounds :math:`[r_-, r_+]` and the discounted
    horizon :math:`H_\gamma` (:func:`discounted_horizon`), with ``headroom`` :math:`h` on each side:

    .. math:: G_- = \min(0, r_-) H_\gamma, \quad G_+ = \max(0, r_+) H_\gamma, \qquad
       [v_{\min}, v_{\max}] = [G_- - h (G_+ - G_-),\; G_+ + h (G_+ - G_-)]

    Every discounted return, of a full episode or of one cut short (hence the 0 in both bounds),
    lies in :math:`[G_-, G_+]`, and so does an n-step target that bootstraps from a value inside
    it; the headroom keeps a critic that overshoots on the way off the edge atoms. dm_control's
    [0, 1] rewards over 1000 steps at gamma 0.99: [-10.0, 110.0].
    """
    low, high = reward_bounds
    if not (math.isfinite(low) and math.isfinite(high) and low <= high):
        raise ValueError(
            f"reward bounds must be finite [low, high], low <= high; got {reward_bounds}"
        )
    if not (horizon > 0 and headroom >= 0):
        raise ValueError(f"need horizon > 0 and headroom >= 0, got {horizon} and {headroom}")
    g_low, g_high = min(0.0, low) * horizon, max(0.0, high) * horizon
    if g_low == g_high:
        raise ValueError(f"reward bounds {reward_bounds} leave every return at 0: no support")
    margin = headroom * (g_high - g_low)
    return g_low - margin, g_high + margin


#: Per-step bounds of the task reward of each external env source: dm_control's suite rewards lie
#: in the unit interval (Tassa et al. 2018, "Reward": r(s, a) in [0, 1]).
SOURCE_REWARD_BOUNDS: dict[str, tuple[float, float]] = {"dm_control": (0.0, 1.0)}


def _source(env: EnvConfig) -> str | None:
    """The source of an external env's ``env.name`` (``dm_control``), ``None`` for the hand."""
    return None if env.name is None else env.name.partition(":")[0]


def derives_support(env: EnvConfig, network: NetworkConfig) -> bool:
    """Whether the task head's support is derived (:func:`derived_support`):
    ``network.derive_support``, or where it is null, for an external env whose reward bounds
    are known (``env.reward_bounds``, or its source's)."""
    if network.derive_support is not None:
        return network.derive_support
    return env.name is not None and (
        env.reward_bounds is not None or _source(env) in SOURCE_REWARD_BOUNDS
    )


def task_reward_bounds(env: EnvConfig) -> tuple[float, float]:
    """``env.reward_bounds``, else its source's (:data:`SOURCE_REWARD_BOUNDS`); a ``ValueError``
    naming the setting to state where neither is known."""
    if env.reward_bounds is not None:
        low, high = env.reward_bounds
        return float(low), float(high)
    if _source(env) in SOURCE_REWARD_BOUNDS:
        return SOURCE_REWARD_BOUNDS[_source(env)]
    raise ValueError(
        f"network.derive_support needs the task reward's per-step bounds: set env.reward_bounds="
        f"[low, high] (known for {sorted(SOURCE_REWARD_BOUNDS)} only; env.name={env.name!r})"
    )


def head_supports(
    reward_keys: Sequence[str],
    *,
    v_min: float,
    v_max: float,
    bounded: bool,
    dense_span: float | None = None,
    spans: Mapping[str, float] | None = None,
) -> tuple[list[float], list[float]]:
    """``(v_min, v_max)`` of each head's support: the critic owns one support per head.

    A head gets ``[v_min, v_max]``, except

    - a *dense* reward (:attr:`Component.dense`: penalties, curiosity) when ``dense_span`` is
      set gets ``[-dense_span, dense_span]``: its return sums a reward paid at every step, so
      its support scales with the horizon (``dense_span`` = per-step bound x
      :func:`discounted_horizon`), while the task's return is one terminal reward and keeps
      the finer ``[v_min, v_max]``; a dense reward named in ``spans`` gets
      ``[-spans[key], spans[key]]`` instead (its own per-step size, e.g. the penalty surprise);
    - with ``bounded``, a head whose reward is never above :attr:`Component.upper_bound` tops
      there (0 for penalties); a head whose bottom would then not lie below its top keeps its
      own bottom and the bound is not applied.
    """
    if dense_span is not None and not dense_span > 0:
        raise ValueError(f"dense_span must be > 0 (or None), got {dense_span}")
    spans = dict(spans or {})
    bad = {k: v for k, v in spans.items() if k not in COMPONENTS or not v > 0}
    if bad:
        raise ValueError(f"spans must map reward keys of {sorted(COMPONENTS)} to > 0, got {bad}")
    lows, highs = [], []
    for key in reward_keys:
        component = COMPONENTS[key]
        span = spans.get(key, dense_span)
        lo, hi = (-span, span) if component.dense and span else (v_min, v_max)
        bound = component.upper_bound
        if bounded and bound is not None and lo < bound:
            hi = min(hi, bound)
        lows.append(float(lo))
        highs.append(float(hi))
    return lows, highs


def critic_supports(
    reward_keys: Sequence[str],
    network: NetworkConfig,
    horizon: float,
    task_support: tuple[float, float] | None = None,
) -> tuple[list[float], list[float]]:
    """Each critic head's ``(v_min, v_max)`` under ``network``'s settings (:func:`head_supports`).

    The task's head spans ``task_support`` where given (:func:`derived_support`), else
    ``[network.v_min, network.v_max]``. A dense head spans ``network.dense_reward_bound`` (the penalty surprise's
    ``network.penalty_surprise_bound`` where set) x ``horizon``, the discounted horizon of an
    episode (:func:`discounted_horizon`): the largest return of a reward of that size at every
    step.
    """
    bound, rsp = network.dense_reward_bound, network.penalty_surprise_bound
    v_min, v_max = task_support or (network.v_min, network.v_max)
    return head_supports(
        reward_keys,
        v_min=v_min,
        v_max=v_max,
        bounded=network.bounded_support,
        dense_span=None if bound is None else bound * horizon,
        spans=None if rsp is None else {keys.PENALTY_SURPRISE: rsp * horizon},
    )
