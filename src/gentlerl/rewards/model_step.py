"""``ModelStep``: one reward model's gradient step, launched as the D4PG learner's is;
``SeedBatchedModelStep``: the same step of S seeds' models as one vmapped step.

The models behind the intrinsic rewards (the penalty and dynamics ensembles, ICM) take one Adam
step per learner update. On a GPU an eager step is a few hundred small kernels (4.5 ms for the
paper's penalty ensemble on an H200, against 0.3 ms replayed as a CUDA graph:
benchmarks/RESULTS.md), so the step follows the learner's ``compile`` / ``cudagraphs`` settings
(:func:`~gentlerl.objectives.compile.compile_step`); on the CPU by default it is the plain step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.objectives import LossModule

from gentlerl.models.stacking import optimizer_rows, share_rows, stack_parameters
from gentlerl.objectives.compile import compile_step


class ModelStep:
    """``step(batch)``: ``loss``'s ``loss_*`` outputs summed, backward, one fused Adam step;
    returns the summed loss as a float.

    Args:
        loss: the model's loss (e.g. :class:`~gentlerl.objectives.EnsembleModelLoss`).
        lr: Adam's step size.
        compile: ``torch.compile`` the loss and its backward.
        cudagraphs: replay the whole step as a CUDA graph (Adam capturable; CUDA only, the
            batch's shape fixed: the models sample ``ensemble_size x model_batch_size``).
    """

    def __init__(
        self, loss: LossModule, lr: float, *, compile: bool = False, cudagraphs: bool = False
    ) -> None:
        device = next(loss.parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(
                f"cudagraphs needs the model on a CUDA device, this one is on {device}"
            )
        self.loss = loss
        # fused: one kernel per step instead of ~10 per parameter tensor
        self._adam_options = {"fused": True, "capturable": cudagraphs}
        self.optimizer = torch.optim.Adam(loss.parameters(), lr=lr, **self._adam_options)
        self._total = compile_step(self._summed_loss, compile=compile, name="a reward model")
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    def _summed_loss(self, batch: TensorDictBase) -> torch.Tensor:
        return sum(v for k, v in self.loss(batch).items() if k.startswith("loss_"))

    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        self.optimizer.zero_grad(set_to_none=True)
        total = self._total(batch)
        total.backward()
        self.optimizer.step()
        return TensorDict({"loss": total.detach()})  # CUDA graphs return tensordicts

    def __call__(self, batch: TensorDictBase) -> float:
        return self._step(batch)["loss"].item()

    def load_optimizer_state(self, state: Mapping[str, Any]) -> None:
        """Adam's saved state, run with this step's kernels (fused, capturable) whatever the
        saved one used."""
        groups = [{**g, **self._adam_options} for g in state["param_groups"]]
        self.optimizer.load_state_dict({**state, "param_groups": groups})


class SeedBatchedModelStep:
    """S reward models (one per seed) stepped together, equal to S :class:`ModelStep` s.

    As :class:`~gentlerl.agent.seeds.SeedBatchedLearner` does for the D4PG heads: each seed's
    ``model_params`` (weights and normaliser statistics) get a leading seed dimension and one
    ``torch.vmap`` of the loss's pure ``losses(batch, params)`` (e.g.
    :meth:`~gentlerl.objectives.EnsembleModelLoss.losses`) runs every seed's ensemble, so the
    kernels per step are one model's, S times wider. The seeds stay independent: each loss reads
    its own parameters, the summed loss gives each its own gradient, and fused Adam is
    elementwise. The models' bootstrap draws differ per seed (``randomness="different"``).

    Args:
        losses: one model loss per seed, of one architecture (built under each seed).
        lr, compile, cudagraphs: as :class:`ModelStep`.
        share: make each loss's ``model_params`` views of its row of the stack
            (:func:`~gentlerl.models.stacking.share_rows`): the seeds' own reward transforms
            and target copies then read the updated models, no :meth:`write_back` needed.

    Calling it with a batch shaped ``[S, ...]`` (seed s's samples in row s, e.g. ``[S, E, B]``)
    takes one step and returns the ``[S]`` summed losses without a host read;
    :meth:`write_back` copies seed s's parameters and statistics into ``losses[s]``.
    """

    def __init__(
        self,
        losses: Sequence[LossModule],
        lr: float,
        *,
        compile: bool = False,
        cudagraphs: bool = False,
        share: bool = False,
    ) -> None:
        if len(losses) < 1:
            raise ValueError("SeedBatchedModelStep needs at least one loss (one per seed), got 0")
        if not callable(getattr(losses[0], "losses", None)):
            raise TypeError(
                f"SeedBatchedModelStep needs a loss with a pure losses(batch, params) (e.g. "
                f"EnsembleModelLoss), got {type(losses[0]).__name__}"
            )
        device = next(losses[0].parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(f"cudagraphs needs the models on a CUDA device, these are on {device}")
        self.losses, self.num_seeds, self.loss = list(losses), len(losses), losses[0]
        self.params = stack_parameters([loss.model_params for loss in losses])
        if share:
            share_rows(self.params, [loss.model_params for loss in losses])
        weights = [v for v in self.params.values(True, True) if isinstance(v, nn.Parameter)]
        self.optimizer = torch.optim.Adam(weights, lr=lr, fused=True, capturable=cudagraphs)
        self._total = compile_step(
            torch.vmap(self._summed_loss, (0, 0), randomness="different"),
            compile=compile,
            name="the seed-batched reward models",
        )
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    def _summed_loss(self, batch: TensorDictBase, params: TensorDictBase) -> torch.Tensor:
        return sum(v for k, v in self.loss.losses(batch, params).items() if k.startswith("loss_"))

    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        self.optimizer.zero_grad(set_to_none=True)
        total = self._total(batch, self.params)
        total.sum().backward()
        self.optimizer.step()
        return TensorDict({"loss": total.detach()})  # CUDA graphs return tensordicts

    def __call__(self, batch: TensorDictBase) -> torch.Tensor:
        if batch.batch_dims < 2 or batch.batch_size[0] != self.num_seeds:
            raise ValueError(
                f"a seed-batched model step needs a batch shaped [num_seeds={self.num_seeds}, "
                f"...], got {tuple(batch.batch_size)}"
            )
        return self._step(batch)["loss"]

    def optimizer_rows(self, optimizers: Sequence[torch.optim.Optimizer]) -> None:
        """Each seed's own optimiser (its :class:`ModelStep`'s) given its row of this one's
        state (:func:`~gentlerl.models.stacking.optimizer_rows`), before its checkpoint."""
        optimizer_rows(self.optimizer, optimizers)

    @torch.no_grad()
    def write_back(self, seed: int) -> LossModule:
        """``losses[seed]`` holding that seed's current parameters and normaliser statistics."""
        self.losses[seed].model_params.update_(self.params[seed])
        return self.losses[seed]
