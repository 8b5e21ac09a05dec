"""``SeedBatchedLearner``: the D4PG updates of S independent agents (seeds) as one batched step.

The fused critic already runs its K heads as ``[K, in, out]`` weights; here the S seeds of one
variant get a leading seed dimension on every parameter (``torch.stack`` of each agent's
:meth:`~gentlerl.objectives.MultiHeadD4PGLoss.network_params`) and one ``torch.vmap`` of the
loss's pure :meth:`~gentlerl.objectives.MultiHeadD4PGLoss.losses` evaluates all of them: the
kernels launched per update are those of one agent, each S times wider. The seeds stay
independent: each loss depends on its own parameters only, the summed loss gives each seed its
own gradient, and Adam is elementwise, so one fused Adam over the stacked parameters is S Adams.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDict, TensorDictBase

from gentlerl.models.stacking import optimizer_rows, share_rows, stack_parameters
from gentlerl.objectives import MultiHeadD4PGLoss
from gentlerl.objectives.compile import compile_step


class SeedBatchedLearner:
    """S D4PG learners (one per seed) updated together, equal to S :class:`Learner` s.

    Args:
        losses: one :class:`~gentlerl.objectives.MultiHeadD4PGLoss` per seed, of one architecture
            (build each under its own seed); their parameters are copied into the stack.
        lr_actor, lr_critic: Adam step sizes of the two parameter groups.
        target_update_period: updates between hard target copies (every seed at once).
        compile: ``torch.compile`` the batched losses (the first update compiles them).
        cudagraphs: replay the whole step as one CUDA graph (its Adam capturable); CUDA only.
        share: make each loss's parameters views of its row of the stack
            (:func:`~gentlerl.models.stacking.share_rows`): the seeds' own actors then act and
            evaluate with the updated weights, no :meth:`write_back` needed.

    :meth:`update` takes a batch shaped ``[S, B]`` (seed s's transitions in row s, on any device:
    it is moved to the learners') and writes its ``[S, B]`` priorities where the batch is;
    :meth:`write_back` copies seed s's parameters into ``losses[s]`` (for its actor, evaluation
    or checkpoint; not needed with ``share``).
    """

    def __init__(
        self,
        losses: Sequence[MultiHeadD4PGLoss],
        *,
        lr_actor: float,
        lr_critic: float,
        target_update_period: int,
        compile: bool = False,
        cudagraphs: bool = False,
        share: bool = False,
    ) -> None:
        if len(losses) < 1:
            raise ValueError("SeedBatchedLearner needs at least one loss (one per seed), got 0")
        if target_update_period < 1:
            raise ValueError(f"target_update_period must be >= 1, got {target_update_period}")
        device = next(losses[0].parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(f"learner.cudagraphs needs a CUDA learner, this one is on {device}")
        self.losses, self.num_seeds, self.device = list(losses), len(losses), device
        self.loss = losses[0]  # its modules run every seed's parameters (vmap)
        self.params = stack_parameters([loss.network_params() for loss in losses])
        for name in ("target_actor", "target_value"):
            self.params[name].apply_(lambda p: p.requires_grad_(False))
        if share:
            share_rows(self.params, [loss.network_params() for loss in losses])
        self.optimizer = torch.optim.Adam(
            [
                {"params": list(self.params["actor"].values(True, True)), "lr": lr_actor},
                {"params": list(self.params["value"].values(True, True)), "lr": lr_critic},
            ],
            fused=True,
            capturable=cudagraphs,
        )
        self.target_update_period = target_update_period
        self.counter = 0
        self._priority_key = self.loss.tensor_keys.priority
        self._in_keys = self.loss.in_keys
        self._losses = compile_step(
            torch.vmap(self.loss.losses, (0, 0), randomness="different"), compile=compile
        )
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        """Every seed's losses, one backward of their sum, one Adam step; returns the ``[S]``
        losses with the ``[S, B]`` priorities, with no host sync."""
        self.optimizer.zero_grad(set_to_none=True)
        out, priority = self._losses(batch, self.params)
        (out["loss_value"] + out["loss_actor"]).sum().backward()
        self.optimizer.step()
        out = out.detach()
        out.set(self._priority_key, priority)
        return out

    def update(self, batch: TensorDictBase) -> TensorDict:
        """One gradient step of every seed on ``batch`` ``[S, B]``; writes its priorities."""
        if batch.batch_dims != 2 or batch.batch_size[0] != self.num_seeds:
            raise ValueError(
                f"a seed-batched update needs a batch shaped [num_seeds={self.num_seeds}, B], "
                f"got {tuple(batch.batch_size)}"
            )
        inputs = batch.select(*self._in_keys, strict=False)
        home = batch.device or inputs.get(self._in_keys[0]).device  # where the replays are
        out = self._step(inputs.to(self.device, non_blocking=True))
        batch.set(self._priority_key, out.pop(self._priority_key).to(home), inplace=True)
        self.counter += 1
        if self.counter % self.target_update_period == 0:
            self._copy_targets()
        return out

    @torch.no_grad()
    def _copy_targets(self) -> None:
        self.params["target_actor"].update_(self.params["actor"])
        self.params["target_value"].update_(self.params["value"])

    def optimizer_rows(self, optimizers: Sequence[torch.optim.Optimizer]) -> None:
        """Each seed's own optimiser (e.g. its :class:`Learner`'s) given its row of this one's
        state (:func:`~gentlerl.models.stacking.optimizer_rows`), before its checkpoint."""
        optimizer_rows(self.optimizer, optimizers)

    @torch.no_grad()
    def write_back(self, seed: int) -> MultiHeadD4PGLoss:
        """``losses[seed]`` holding that seed's current online and target parameters."""
        self.losses[seed].network_params().update_(self.params[seed])
        return self.losses[seed]
