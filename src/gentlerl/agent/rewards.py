"""``IntrinsicRewards``: a variant's reward transforms, the models behind them and how they learn.

The models learn from 1-step transitions (s_t, a_t, s_{t+1}, r^f_t) in their own uniform buffer;
every model update is followed by the paper's schedule: hard target copies every
``target_period`` updates, and the curiosity rewards switched on after ``reward_delay`` updates.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import torch
from tensordict import TensorDictBase
from torchrl.data import ReplayBuffer
from torchrl.envs.transforms import Compose
from torchrl.objectives import HardUpdate

from gentlerl import keys
from gentlerl.agent.variants import COMPONENTS, Ingredients, reward_keys
from gentlerl.data import make_model_buffer
from gentlerl.objectives import EnsembleModelLoss
from gentlerl.transforms import ImpactPenalty, ModelRewardTransform

if TYPE_CHECKING:
    from gentlerl.training.config import GentlenessConfig


class IntrinsicRewards:
    """The reward transforms of a variant, their models' losses, optimisers, schedule and buffer.

    Attributes:
        transform: writes ``impact``, ``penalty`` and the variant's other rewards under
            ``"next"``; apply it to collected batches (``transform(batch)``) or append it to an env.
        reward_keys: the reward components, in critic-head order.
        losses: model name -> its loss (``{}`` without learned rewards).
        buffer: the models' 1-step transitions (``None`` without learned rewards).

    Works on any env with ``observation``, ``action`` and a force entry ``force_key`` shaped
    ``[..., n_sites, n_channels]`` (the hand's ``touch``, ``[5, 3]``); ``feature_shapes`` names the
    entries the dynamics model predicts (used by the variants with dynamics surprise only).
    """

    def __init__(
        self,
        variant: str,
        settings: GentlenessConfig,
        *,
        obs_dim: int,
        action_dim: int,
        feature_shapes: Mapping[str, Sequence[int]],
        seed: int = 0,
        force_key: str = keys.TOUCH,
    ) -> None:
        self.reward_keys = reward_keys(variant)
        self.settings = settings
        ing = Ingredients(obs_dim, action_dim, feature_shapes, settings, seed)
        # impact is logged for every variant; the force key is any [..., n_sites, n_channels] entry
        transforms: list = [ImpactPenalty(settings.lam, in_keys=[force_key])]
        self.losses: dict[str, Any] = {}
        self._updaters: dict[str, HardUpdate] = {}
        for key in self.reward_keys:
            component = COMPONENTS[key]
            if component.build is None:
                continue
            part = component.build(ing)
            transforms.append(part.transform)
            if part.loss is not None:
                self.losses[component.model] = part.loss
            if part.target_period is not None:
                # TorchRL's HardUpdate copies on the (interval + 1)-th step() call.
                interval = part.target_period - 1
                self._updaters[component.model] = HardUpdate(
                    part.loss, value_network_update_interval=interval
                )
        self.transform = Compose(*transforms)
        self.optimizers = {
            # fused: one kernel per step instead of ~10 per parameter tensor
            name: torch.optim.Adam(loss.parameters(), lr=settings.lr_model, fused=True)
            for name, loss in self.losses.items()
        }
        self.buffer: ReplayBuffer | None = (
            make_model_buffer(settings.model_buffer_size) if self.losses else None
        )

    @property
    def gated_transforms(self) -> list[ModelRewardTransform]:
        return [t for t in self.transform if isinstance(t, ModelRewardTransform)]

    @property
    def intrinsic_on(self) -> bool:
        gated = self.gated_transforms
        return bool(gated) and bool(gated[0].active)

    def extend(self, batch: TensorDictBase) -> None:
        """Keep a collected (transformed) batch's 1-step transitions for the models."""
        if self.buffer is not None:
            touch_grid = (keys.TOUCH_GRID, ("next", keys.TOUCH_GRID))
            self.buffer.extend(batch.exclude(*touch_grid, "collector").reshape(-1))

    def update(self, num_updates: int) -> dict[str, float]:
        """One gradient step of every model, then :meth:`step`; returns ``model_<name>`` losses."""
        metrics = {}
        b = self.settings.model_batch_size
        for name, loss in self.losses.items():
            if isinstance(loss, EnsembleModelLoss):
                e = loss.ensemble_size
                batch = self.buffer.sample(e * b).reshape(e, b)  # a bootstrap batch per member
            else:
                batch = self.buffer.sample(b)
            out = loss(batch)
            total = sum(v for k, v in out.items() if k.startswith("loss_"))
            self.optimizers[name].zero_grad()
            total.backward()
            self.optimizers[name].step()
            metrics[f"model_{name}"] = total.item()
        self.step(num_updates)
        return metrics

    def step(self, num_updates: int) -> None:
        """Call once after each model update, with the total update count (paper's schedule).

        Copies each model into its target every ``target_period`` calls (TorchRL ``HardUpdate``)
        and switches the intrinsic rewards on once ``num_updates >= reward_delay``.
        """
        for updater in self._updaters.values():
            updater.step()
        on = num_updates >= self.settings.reward_delay
        for t in self.gated_transforms:
            t.active.fill_(on)

    def state_dict(self) -> dict[str, Any]:
        """Models, optimisers and schedule (the buffer is saved with the other buffers)."""
        return {
            "losses": {name: loss.state_dict() for name, loss in self.losses.items()},
            "optimizers": {name: o.state_dict() for name, o in self.optimizers.items()},
            "active": self.intrinsic_on,
            "target_counters": {name: u.counter for name, u in self._updaters.items()},
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        for name, loss in self.losses.items():
            loss.load_state_dict(state["losses"][name])
            self.optimizers[name].load_state_dict(state["optimizers"][name])
        for t in self.gated_transforms:
            t.active.fill_(bool(state["active"]))
        for name, counter in state["target_counters"].items():
            self._updaters[name].counter = counter
