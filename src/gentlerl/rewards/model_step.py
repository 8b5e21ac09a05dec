"""``ModelStep``: the gradient step of S seeds' reward models as one step; S = 1 for one run.

The models behind the intrinsic rewards (the penalty and dynamics ensembles, ICM) take one Adam
step per learner update. As the D4PG :class:`~gentlerl.agent.Learner` does for its heads, the
seeds' ``model_params`` (weights and normaliser statistics) are one
:class:`~gentlerl.models.stacking.SeedStack` (a leading seed axis, each seed's own tensors views
of its row: its reward transform and target copy read the trained model with no copy; one fused
Adam), and the loss's pure ``losses(batch, params)`` runs on every row: one
``torch.vmap`` for several seeds (their bootstrap draws differ, ``randomness="different"``), a
plain call on row 0 for one. On a GPU an eager step is a few hundred small kernels (4.5 ms for
the paper's penalty ensemble on an H200, against 0.3 ms replayed as a CUDA graph), so the step
follows the learner's ``compile`` / ``cudagraphs`` settings
(:func:`~gentlerl.objectives.launch.compile_step`); on the CPU by default it is the plain step.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.objectives import LossModule

from gentlerl.functional.constraint import is_finite_number
from gentlerl.models.stacking import SeedStack, over_seeds
from gentlerl.objectives.launch import compile_step


class ModelStep:
    """``step(batch)``: each seed's ``loss_*`` outputs summed, one backward of their sum, one
    fused Adam step; returns the ``[S]`` summed losses with no host read.

    Args:
        loss: the model's loss, with a pure ``losses(batch, params)`` over its ``model_params``
            (:class:`~gentlerl.objectives.EnsembleModelLoss`, :class:`~gentlerl.objectives.ICMLoss`),
            or one per seed, of one architecture (each built under its own seed).
        lr: Adam's step size.
        compile: ``torch.compile`` the losses and their backward.
        cudagraphs: replay the whole step as a CUDA graph (Adam capturable; CUDA only, the
            batch's shape fixed: the models sample ``ensemble_size x model_batch_size``).

    The batch carries a leading seed axis: ``[S, ...]``, seed s's samples in row s (e.g.
    ``[S, E, B]`` for an ensemble). Per seed: :meth:`optimizer_state` and
    :meth:`load_optimizer_state`.
    """

    def __init__(
        self,
        loss: LossModule | Sequence[LossModule],
        lr: float,
        *,
        compile: bool = False,
        cudagraphs: bool = False,
    ) -> None:
        losses = [loss] if isinstance(loss, nn.Module) else list(loss)
        if not losses:
            raise ValueError("ModelStep needs at least one loss (one per seed), got 0")
        if not callable(getattr(losses[0], "losses", None)):
            raise TypeError(
                f"ModelStep needs a loss with a pure losses(batch, params) (e.g. "
                f"EnsembleModelLoss), got {type(losses[0]).__name__}"
            )
        if not (is_finite_number(lr) and lr > 0):
            raise ValueError(f"lr must be a finite number > 0, got {lr!r}")
        device = next(losses[0].parameters()).device
        if cudagraphs and device.type != "cuda":
            raise ValueError(f"cudagraphs needs the models on a CUDA device, these are on {device}")
        self.losses, self.num_seeds, self.loss = losses, len(losses), losses[0]
        self.stack = SeedStack([seed.model_params for seed in losses], lr, capturable=cudagraphs)
        self.params, self.optimizer = self.stack.params, self.stack.optimizer
        self._total = compile_step(
            over_seeds(self._summed_loss, self.num_seeds),
            compile=compile,
            name="the reward models",
        )
        self._step = compile_step(self._gradient_step, cudagraphs=cudagraphs)

    def _summed_loss(self, batch: TensorDictBase, params: TensorDictBase) -> torch.Tensor:
        return sum(v for k, v in self.loss.losses(batch, params).items() if k.startswith("loss_"))

    def _gradient_step(self, batch: TensorDictBase) -> TensorDict:
        total = self._total(batch, self.params)
        self.stack.descend(total.sum())
        return TensorDict({"loss": total.detach()})  # CUDA graphs return tensordicts

    def __call__(self, batch: TensorDictBase) -> torch.Tensor:
        if batch.batch_dims < 2 or batch.batch_size[0] != self.num_seeds:
            raise ValueError(
                f"a model step needs a batch shaped [num_seeds={self.num_seeds}, ...], "
                f"got {tuple(batch.batch_size)}"
            )
        return self._step(batch)["loss"]

    def optimizer_state(self, seed: int = 0) -> dict[str, Any]:
        """Seed ``seed``'s row of Adam's state: what a run of its own saves."""
        return self.stack.row(seed)

    def load_optimizer_state(self, state: Mapping[str, Any], seed: int = 0) -> None:
        """Seed ``seed``'s saved Adam state (:meth:`optimizer_state`'s format) into its row, run
        with this step's kernels (fused, capturable) whatever the saved one used."""
        self.stack.load_row(state, seed)


class SeedBatchedModelStep(ModelStep):
    """Deprecated since 0.2.0, removed in 0.3.0: :class:`ModelStep` takes one loss per seed
    (its rows always shared with each seed's loss; ``share`` is ignored)."""

    def __init__(
        self, losses: Sequence[LossModule], lr: float, *, share: bool = True, **options: Any
    ) -> None:
        warnings.warn(
            "gentlerl.rewards.model_step.SeedBatchedModelStep is deprecated since 0.2.0 and "
            "removed in 0.3.0: use ModelStep(losses, lr), which takes one loss per seed",
            DeprecationWarning,
            stacklevel=2,
        )
        super().__init__(list(losses), lr, **options)
