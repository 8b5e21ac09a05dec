"""The reward transforms, models and losses of each paper variant, built in one call."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import torch
from torchrl.envs.transforms import Compose
from torchrl.objectives import HardUpdate
from torchrl.objectives.common import LossModule

from gentlerl import keys
from gentlerl.models.ensemble import DynamicsModel, PenaltyModel
from gentlerl.models.icm import ICMModel
from gentlerl.objectives.models import EnsembleModelLoss, ICMLoss
from gentlerl.transforms.base import ModelRewardTransform
from gentlerl.transforms.icm import ICMReward
from gentlerl.transforms.impact import ImpactPenalty
from gentlerl.transforms.surprise import DynamicsSurprise, PenaltySurprise

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
}

#: The hand env's state feature groups, as the paper's three dynamics ensembles predict them.
HAND_FEATURES: dict[str, tuple[int, ...]] = {
    keys.JOINT_POS: (24,),
    keys.JOINT_VEL: (24,),
    keys.TOUCH: (5, 3),
}


@dataclass
class RewardStack:
    """What the training loop needs for one variant.

    Attributes:
        transform: writes ``impact``, ``penalty`` and the variant's intrinsic rewards under
            ``"next"``; apply it to collected batches (``transform(batch)``) or append it to an env.
        reward_keys: the reward components, in critic-head order.
        model_losses: name -> loss of each model to train (``{}`` without intrinsic rewards).
        target_periods: name -> model updates between hard target copies.
        reward_delay: model updates before the intrinsic rewards switch on.
    """

    transform: Compose
    reward_keys: list[str]
    model_losses: dict[str, LossModule] = field(default_factory=dict)
    target_periods: dict[str, int] = field(default_factory=dict)
    reward_delay: int = 0
    _updaters: dict[str, HardUpdate] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for name, loss in self.model_losses.items():
            if name in self.target_periods:
                # TorchRL's HardUpdate copies on the (interval + 1)-th step() call.
                period = self.target_periods[name]
                self._updaters[name] = HardUpdate(loss, value_network_update_interval=period - 1)

    @property
    def gated_transforms(self) -> list[ModelRewardTransform]:
        return [t for t in self.transform if isinstance(t, ModelRewardTransform)]

    @property
    def intrinsic_on(self) -> bool:
        gated = self.gated_transforms
        return bool(gated) and bool(gated[0].active)

    def step(self, num_updates: int) -> None:
        """Call once after each model update, with the total update count (paper's schedule).

        Copies each model into its target every ``target_periods[name]`` calls (TorchRL
        ``HardUpdate``) and switches the intrinsic rewards on once ``num_updates >= reward_delay``.
        """
        for updater in self._updaters.values():
            updater.step()
        on = num_updates >= self.reward_delay
        for t in self.gated_transforms:
            t.active.fill_(on)

    def state_dict(self) -> dict[str, Any]:
        return {
            "losses": {name: loss.state_dict() for name, loss in self.model_losses.items()},
            "active": self.intrinsic_on,
            "target_counters": {name: u.counter for name, u in self._updaters.items()},
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        for name, loss in self.model_losses.items():
            loss.load_state_dict(state["losses"][name])
        for t in self.gated_transforms:
            t.active.fill_(bool(state["active"]))
        for name, counter in state["target_counters"].items():
            self._updaters[name].counter = counter


def make_reward_transforms(
    variant: str,
    *,
    obs_dim: int = 63,
    action_dim: int = 20,
    feature_shapes: Mapping[str, Sequence[int]] | None = None,
    lam: tuple[float, float] = (2.0, 2.0),
    lam_prime: tuple[float, float] = (2.0, 2.0),
    reward_delay: int = 20_000,
    dynamics_target_period: int = 5000,
    penalty_target_period: int = 1000,
    ensemble_size: int = 5,
    hidden: int = 128,
    surprise_scale: float = 1.0,
    surprise_nll_floor: float | None = None,
    icm_eta: float = 1.0,
    seed: int = 0,
) -> RewardStack:
    """Build the transforms, models and losses of a paper variant (see :data:`VARIANTS`).

    ``ImpactPenalty`` is always included (``impact`` is logged for every variant, for the paper's
    impact histograms); the models are built only where the variant uses their reward. Defaults are
    the paper's: lambda = [2, 2], 5 members x 3 x 128 units, target periods 5000 / 1000, delay 20k.
    """
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; expected one of {sorted(VARIANTS)}")
    for name, value in (
        ("reward_delay", reward_delay),
        ("dynamics_target_period", dynamics_target_period - 1),
        ("penalty_target_period", penalty_target_period - 1),
    ):
        if value < 0:
            raise ValueError(f"{name} must be >= {0 if name == 'reward_delay' else 1}, got {value}")
    reward_keys = list(VARIANTS[variant])
    features = dict(feature_shapes or HAND_FEATURES)
    hidden_layers = (hidden, hidden, hidden)
    transforms: list = [ImpactPenalty(lam)]
    losses: dict[str, LossModule] = {}
    periods: dict[str, int] = {}
    if keys.DYNAMICS_SURPRISE in reward_keys:
        model = DynamicsModel(
            obs_dim, action_dim, features, ensemble_size, hidden_layers, seed=seed
        )
        losses["dynamics"] = EnsembleModelLoss(model, name="dynamics")
        periods["dynamics"] = dynamics_target_period
        transforms.append(DynamicsSurprise(losses["dynamics"], scale=surprise_scale))
    if keys.PENALTY_SURPRISE in reward_keys:
        model = PenaltyModel(obs_dim, action_dim, ensemble_size, hidden_layers, seed=seed + 1)
        losses["penalty"] = EnsembleModelLoss(model, name="penalty")
        periods["penalty"] = penalty_target_period
        transforms.append(
            PenaltySurprise(
                losses["penalty"],
                lam_prime=lam_prime,
                scale=surprise_scale,
                nll_floor=surprise_nll_floor,
            )
        )
    if keys.ICM_REWARD in reward_keys:
        with torch.random.fork_rng():
            torch.manual_seed(seed + 2)
            losses["icm"] = ICMLoss(ICMModel(obs_dim, action_dim))
        transforms.append(ICMReward(losses["icm"], eta=icm_eta))
    return RewardStack(
        transform=Compose(*transforms),
        reward_keys=reward_keys,
        model_losses=losses,
        target_periods=periods,
        reward_delay=reward_delay,
    )
