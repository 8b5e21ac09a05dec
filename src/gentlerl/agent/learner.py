"""``Learner``: the multi-head D4PG loss, one grouped optimiser and the target updater."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.objectives import HardUpdate

from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.objectives.compile import compile_step


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

    The gradient step (losses, backward, one fused Adam step over both parameter groups) is a
    pure function of the batch's loss inputs: it returns the losses and the per-sample priorities
    and leaves the batch alone, so its losses can be compiled (``compile``, TorchRL's sota
    pattern) and the whole step captured in a CUDA graph (``cudagraphs``, with
    ``tensordict.nn.CudaGraphModule``). The priorities are written into the batch, and the target
    copy made, outside that step.

    Args:
        loss: the multi-head D4PG loss (it holds the actor, the critics and their targets).
        lr_actor, lr_critic: Adam step sizes of the two parameter groups.
        target_update_period: updates between hard target copies (Acme: 100).
        compile: ``torch.compile`` the losses and their backward (the first update compiles them:
            seconds to minutes).
        cudagraphs: replay the whole step as a CUDA graph (its Adam capturable); CUDA only.
        separate_policy: act with a CPU copy of the actor (:attr:`policy`); default: when the
            learner is not on the CPU.
    """

    def __init__(
        self,
        loss: MultiHeadD4PGLoss,
        *,
        lr_actor: float,
        lr_critic: float,
        target_update_period: int,
        compile: bool = False,
        cudagraphs: bool = False,
        separate_policy: bool | None = None,
    ) -> None:
        if target_update_period < 1:
            raise ValueError(f"target_update_period must be >= 1, got {target_update_period}")
        device = next(loss.parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(f"learner.cudagraphs needs a CUDA learner, this one is on {device}")
        self.loss, self.device = loss, device
        separate = device.type != "cpu" if separate_policy is None else separate_policy
        self._policy = copy.deepcopy(loss.actor_network).cpu() if separate else loss.actor_network
        # One fused kernel per parameter group instead of ~10 small ones per parameter.
        self._adam_options = {"fused": True, "foreach": None, "capturable": cudagraphs}
        self.optimizer = torch.optim.Adam(
            [
                {"params": list(loss.actor_network_params.values(True, True)), "lr": lr_actor},
                {"params": list(loss.value_network_params.values(True, True)), "lr": lr_critic},
            ],
            **self._adam_options,
        )
        # TorchRL's HardUpdate copies on the (interval + 1)-th step.
        self.target_updater = HardUpdate(
            loss, value_network_update_interval=target_update_period - 1
        )
        self._in_keys = loss.in_keys
        self._priority_key = loss.tensor_keys.priority
        # Compiled: the losses (AOTAutograd compiles their backward too). The fused Adam step is one
        # native kernel per group; dynamo would only graph-break around it.
        self._losses = compile_step(self._losses_and_priorities, compile=compile)
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    @property
    def actor(self) -> torch.nn.Module:
        """The actor being trained (on the learner's device)."""
        return self.loss.actor_network

    @property
    def policy(self) -> torch.nn.Module:
        """The actor that acts, on the CPU: :attr:`actor` itself on a CPU learner, else a copy
        as of the last :meth:`sync_policy`."""
        return self._policy

    @torch.no_grad()
    def sync_policy(self) -> None:
        """Copy the trained actor's parameters into :attr:`policy` (nothing on a CPU learner)."""
        if self._policy is not self.loss.actor_network:
            self._policy.load_state_dict(self.loss.actor_network.state_dict())

    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        """Losses, backward, Adam step; returns the losses and the priorities (no host sync)."""
        self.optimizer.zero_grad(set_to_none=True)
        out, total = self._losses(batch)
        total.backward()
        self.optimizer.step()
        return out.detach()

    def _losses_and_priorities(self, batch: TensorDictBase) -> tuple[TensorDict, torch.Tensor]:
        """The loss's outputs with the priorities, and the loss to minimise."""
        out = self.loss(batch)
        out.set(self._priority_key, batch.get(self._priority_key))
        return out, out["loss_value"] + out["loss_actor"]  # disjoint parameters

    def update(self, batch: TensorDictBase) -> TensorDict:
        """One gradient step on ``batch`` (its ``td_error`` is written for the priorities)."""
        inputs = batch.select(*self._in_keys, strict=False)
        home = batch.device or inputs.get(self._in_keys[0]).device  # where the replay is
        out = self._step(inputs.to(self.device, non_blocking=True))
        priority = out.pop(self._priority_key).to(home)
        batch.set(self._priority_key, priority, inplace=True)
        self.target_updater.step()
        return out

    @property
    def state(self) -> TrainingState:
        return TrainingState(
            networks=self.loss.state_dict(),
            optimizer=self.optimizer.state_dict(),
            target_counter=self.target_updater.counter,
        )

    def restore(self, state: TrainingState) -> None:
        self.loss.load_state_dict(state.networks)
        # This learner's Adam kernels (fused, capturable), whatever the saved state was run with.
        groups = [{**g, **self._adam_options} for g in state.optimizer["param_groups"]]
        self.optimizer.load_state_dict({**state.optimizer, "param_groups": groups})
        self.target_updater.counter = state.target_counter
        self.sync_policy()
