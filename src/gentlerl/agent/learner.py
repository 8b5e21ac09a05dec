"""``Learner``: the multi-head D4PG update of S agents (seeds) as one step; S = 1 for a plain run.

Every parameter of the online and target actor and critics gets a leading seed axis, each
seed's own tensors views of its row, in one :class:`~gentlerl.models.stacking.SeedStack` of the
losses' :meth:`~gentlerl.objectives.MultiHeadD4PGLoss.network_params` (with its fused Adam), so
a seed's actor acts, evaluates and is checkpointed with the trained weights and no copy. The loss's pure
:meth:`~gentlerl.objectives.MultiHeadD4PGLoss.losses` runs on every row: one ``torch.vmap`` over
the seeds when S > 1 (the kernels of one agent, S times wider), a plain call on row 0 when
S = 1. The seeds stay independent: each loss reads its own parameters, the summed loss gives each
its own gradient, and Adam is elementwise, so one fused Adam over the stack is S Adams.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase

from gentlerl.functional.constraint import is_finite_number
from gentlerl.models.stacking import SeedStack, over_seeds
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.objectives.launch import compile_step


@dataclass
class TrainingState:
    """Everything one seed's learner needs to continue, in one object (as Acme's D4PG
    ``TrainingState``); the format of a run of its own, whatever group it trained in.

    Attributes:
        networks: the seed's loss's state dict: online and target actor and critic parameters.
        optimizer: its Adam's state (actor and critic parameter groups), without a seed axis.
        target_counter: updates since the last target copy.
    """

    networks: dict[str, Any]
    optimizer: dict[str, Any]
    target_counter: int


class Learner:
    """D4PG updates: both losses, one optimiser step, the target copy when it is due.

    The gradient step (losses, backward, one fused Adam step over both parameter groups) is a
    pure function of the batch's loss inputs: it returns the losses and the per-sample priorities
    and leaves the batch alone, so its losses can be compiled (``compile``, TorchRL's sota
    pattern) and the whole step captured in a CUDA graph (``cudagraphs``, with
    ``tensordict.nn.CudaGraphModule``). The priorities are written into the batch, and the target
    copy made, outside that step.

    Args:
        loss: the multi-head D4PG loss (it holds the actor, the critics and their targets), or
            one per seed, of one architecture (each built under its own seed).
        lr_actor, lr_critic: Adam step sizes of the two parameter groups.
        target_update_period: updates between hard target copies (Acme: 100), every seed at once.
        compile: ``torch.compile`` the losses and their backward (the first update compiles them:
            seconds to minutes).
        cudagraphs: replay the whole step as a CUDA graph (its Adam capturable); CUDA only.
        separate_policy: act with CPU copies of the actors (:meth:`policy_of`); default: when
            the learner is not on the CPU.

    :meth:`update` takes a batch shaped ``[S, B]`` (seed s's transitions in row s), or ``[B]``
    when S = 1, on any device, and writes its priorities where the batch is. Per seed:
    :meth:`policy_of`, :meth:`state_of`, :meth:`restore`; with one seed, :attr:`policy`,
    :attr:`state`, :attr:`actor` and :attr:`loss` are its own.
    """

    def __init__(
        self,
        loss: MultiHeadD4PGLoss | Sequence[MultiHeadD4PGLoss],
        *,
        lr_actor: float,
        lr_critic: float,
        target_update_period: int,
        compile: bool = False,
        cudagraphs: bool = False,
        separate_policy: bool | None = None,
    ) -> None:
        losses = [loss] if isinstance(loss, MultiHeadD4PGLoss) else list(loss)
        _check_options(len(losses), lr_actor, lr_critic, target_update_period)
        device = next(losses[0].parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(f"learner.cudagraphs needs a CUDA learner, this one is on {device}")
        self.losses, self.num_seeds, self.device = losses, len(losses), device
        for seed in losses:  # their targets are copied here (TorchRL warns of a loss without)
            seed._has_update_associated = dict.fromkeys(seed._has_update_associated, True)
        self.stack = SeedStack(
            [seed.network_params() for seed in losses],
            {"actor": lr_actor, "value": lr_critic},  # the targets: frozen
            capturable=cudagraphs,
        )
        self.params, self.optimizer = self.stack.params, self.stack.optimizer
        separate = device.type != "cpu" if separate_policy is None else separate_policy
        self._policies = [
            copy.deepcopy(seed.actor_network).cpu() if separate else seed.actor_network
            for seed in losses
        ]
        self.target_update_period = target_update_period
        #: Updates since the last target copy (a copy comes when it reaches the period).
        self.target_counter = 0
        self._in_keys = losses[0].in_keys
        self._priority_key = losses[0].tensor_keys.priority
        # Compiled: the losses (AOTAutograd compiles their backward too). The fused Adam step is one
        # native kernel per group; dynamo would only graph-break around it.
        self._losses = compile_step(over_seeds(losses[0].losses, self.num_seeds), compile=compile)
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    # -- one seed's views ----------------------------------------------------------------
    @property
    def loss(self) -> MultiHeadD4PGLoss:
        """The loss whose modules run every seed's parameters (seed 0's own)."""
        return self.losses[0]

    @property
    def actor(self) -> torch.nn.Module:
        """The actor being trained (on the learner's device); one seed only."""
        return self._one_seed("actor").actor_network

    @property
    def policy(self) -> torch.nn.Module:
        """The actor that acts (:meth:`policy_of` the one seed)."""
        self._one_seed("policy")
        return self._policies[0]

    def policy_of(self, seed: int) -> torch.nn.Module:
        """Seed ``seed``'s acting actor, on the CPU: its trained actor itself on a CPU learner,
        else a copy as of the last :meth:`sync_policy`."""
        return self._policies[self._seat(seed)]

    @torch.no_grad()
    def sync_policy(self, seed: int | None = None) -> None:
        """Copy the trained actors' parameters into their acting copies (``seed``: only that
        seed's; nothing on a CPU learner)."""
        seats = range(self.num_seeds) if seed is None else [self._seat(seed)]
        for s in seats:
            if self._policies[s] is not self.losses[s].actor_network:
                self._policies[s].load_state_dict(self.losses[s].actor_network.state_dict())

    # -- the update ----------------------------------------------------------------------
    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        """Every seed's losses, one backward of their sum, one Adam step; returns the ``[S]``
        losses with the ``[S, B]`` priorities, with no host sync."""
        out, priority = self._losses(batch, self.params)
        self.stack.descend((out["loss_value"] + out["loss_actor"]).sum())  # disjoint parameters
        out = out.detach()
        out.set(self._priority_key, priority)
        return out

    def update(self, batch: TensorDictBase) -> TensorDict:
        """One gradient step of every seed on ``batch`` (``[S, B]``, or ``[B]`` with one seed);
        writes its priorities (``td_error``) into it. Returns the losses: ``[S]`` entries, or
        scalars for a ``[B]`` batch."""
        one = batch.batch_dims == 1 and self.num_seeds == 1
        if not one and (batch.batch_dims != 2 or batch.batch_size[0] != self.num_seeds):
            raise ValueError(
                f"Learner.update needs a batch shaped [num_seeds={self.num_seeds}, B]"
                f"{' or [B]' if self.num_seeds == 1 else ''}, got {tuple(batch.batch_size)}"
            )
        inputs = batch.select(*self._in_keys, strict=False)
        inputs = inputs.unsqueeze(0) if one else inputs
        home = batch.device or inputs.get(self._in_keys[0]).device  # where the replays are
        out = self._step(inputs.to(self.device, non_blocking=True))
        priority = out.pop(self._priority_key).to(home)
        batch.set(self._priority_key, priority[0] if one else priority, inplace=True)
        self.target_counter += 1
        if self.target_counter >= self.target_update_period:
            self._copy_targets()
        return out[0] if one else out

    @torch.no_grad()
    def _copy_targets(self) -> None:
        """Hard target copies of every seed, buffers included (as Acme's D4PG)."""
        self.params["target_actor"].update_(self.params["actor"])
        self.params["target_value"].update_(self.params["value"])
        self.target_counter = 0

    # -- state ---------------------------------------------------------------------------
    @property
    def state(self) -> TrainingState:
        """:meth:`state_of` the one seed."""
        self._one_seed("state")
        return self.state_of(0)

    def state_of(self, seed: int) -> TrainingState:
        """Seed ``seed``'s networks, its row of the optimiser and the target counter: what a
        run of its own saves."""
        s = self._seat(seed)
        return TrainingState(
            networks=self.losses[s].state_dict(),
            optimizer=self.stack.row(s),
            target_counter=self.target_counter,
        )

    def restore(self, state: TrainingState, seed: int = 0) -> None:
        """Seed ``seed``'s :class:`TrainingState` into its row (networks, optimiser row, the
        target counter the seeds share), run with this learner's Adam kernels whatever the saved
        ones used."""
        s = self._seat(seed)
        self.losses[s].load_state_dict(state.networks)  # into the shared rows, in place
        self.stack.load_row(state.optimizer, s)
        self.target_counter = int(state.target_counter) % self.target_update_period
        self.sync_policy(s)

    def _seat(self, seed: int) -> int:
        if not 0 <= seed < self.num_seeds:
            raise IndexError(f"seed index {seed} out of range for {self.num_seeds} seeds")
        return seed

    def _one_seed(self, what: str) -> MultiHeadD4PGLoss:
        if self.num_seeds != 1:
            raise ValueError(f"Learner.{what} is one seed's; this learner has {self.num_seeds}")
        return self.losses[0]


def _check_options(num_seeds: int, lr_actor: float, lr_critic: float, period: int) -> None:
    """One-line refusals of the learner's settings, before anything is allocated."""
    if num_seeds < 1:
        raise ValueError("Learner needs at least one loss (one per seed), got 0")
    for name, lr in (("lr_actor", lr_actor), ("lr_critic", lr_critic)):
        if not (is_finite_number(lr) and lr > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {lr!r}")
    if isinstance(period, bool) or not isinstance(period, int) or period < 1:
        raise ValueError(f"target_update_period must be >= 1, got {period!r}")


class SeedBatchedLearner(Learner):
    """Deprecated since 0.2.0, removed in 0.3.0: :class:`Learner` takes one loss per seed.

    Its rows are always shared with each seed's loss (``share`` is ignored); a seed's state is
    :meth:`Learner.state_of`, its actor :meth:`Learner.policy_of`."""

    def __init__(
        self, losses: Sequence[MultiHeadD4PGLoss], *, share: bool = True, **options: Any
    ) -> None:
        warnings.warn(
            "gentlerl.agent.SeedBatchedLearner is deprecated since 0.2.0 and removed in 0.3.0: "
            "use gentlerl.agent.Learner(losses), which takes one loss per seed",
            DeprecationWarning,
            stacklevel=2,
        )
        super().__init__(list(losses), **options)

    def write_back(self, seed: int) -> MultiHeadD4PGLoss:
        """Seed ``seed``'s loss (its tensors are already views of its row: nothing to copy)."""
        return self.losses[self._seat(seed)]

    def optimizer_rows(self, optimizers: Sequence[torch.optim.Optimizer]) -> None:
        """Each seed's own optimiser given its row of this one's state (:meth:`state_of`)."""
        for s, optimizer in enumerate(optimizers):
            optimizer.load_state_dict(self.stack.row(s))
