"""``Learner``: the multi-head D4PG loss, one grouped optimiser and the target updater."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.objectives import HardUpdate, group_optimizers

from gentlerl.objectives import MultiHeadD4PGLoss


@dataclass
class TrainingState:
    """Everything the learner needs to continue, in one object (as Acme's D4PG ``TrainingState``).

    Attributes:
        networks: the loss's state dict: online and target actor and critic parameters.
        optimizer: the grouped Adam's state (actor and critic parameter groups).
        target_counter: updates since the last target copy.
    """

    networks: dict[str, Any]
    optimizer: dict[str, Any]
    target_counter: int


class Learner:
    """One D4PG update: both losses, one optimiser step, the target copy when it is due.

    Args:
        loss: the multi-head D4PG loss (it holds the actor, the critics and their targets).
        lr_actor, lr_critic: Adam step sizes of the two parameter groups.
        target_update_period: updates between hard target copies (Acme: 100).
    """

    def __init__(
        self,
        loss: MultiHeadD4PGLoss,
        *,
        lr_actor: float,
        lr_critic: float,
        target_update_period: int,
    ) -> None:
        if target_update_period < 1:
            raise ValueError(f"target_update_period must be >= 1, got {target_update_period}")
        self.loss = loss
        self.optimizer = group_optimizers(
            torch.optim.Adam(loss.actor_network_params.values(True, True), lr=lr_actor),
            torch.optim.Adam(loss.value_network_params.values(True, True), lr=lr_critic),
        )
        # TorchRL's HardUpdate copies on the (interval + 1)-th step.
        self.target_updater = HardUpdate(
            loss, value_network_update_interval=target_update_period - 1
        )

    @property
    def actor(self) -> torch.nn.Module:
        return self.loss.actor_network

    def update(self, batch: TensorDictBase) -> TensorDict:
        """One gradient step on ``batch`` (its ``td_error`` is written for the priorities)."""
        out = self.loss(batch)
        self.optimizer.zero_grad()
        (out["loss_value"] + out["loss_actor"]).backward()  # disjoint parameters
        self.optimizer.step()
        self.target_updater.step()
        return out.detach()

    @property
    def state(self) -> TrainingState:
        return TrainingState(
            networks=self.loss.state_dict(),
            optimizer=self.optimizer.state_dict(),
            target_counter=self.target_updater.counter,
        )

    def restore(self, state: TrainingState) -> None:
        self.loss.load_state_dict(state.networks)
        self.optimizer.load_state_dict(state.optimizer)
        self.target_updater.counter = state.target_counter
