"""``ModelStep``: one reward model's gradient step, launched as the D4PG learner's is.

The models behind the intrinsic rewards (the penalty and dynamics ensembles, ICM) take one Adam
step per learner update. On a GPU an eager step is a few hundred small kernels (4.5 ms for the
paper's penalty ensemble on an H200, against 0.3 ms replayed as a CUDA graph:
benchmarks/RESULTS.md), so the step follows the learner's ``compile`` / ``cudagraphs`` settings
(:func:`~gentlerl.objectives.compile.compile_step`); on the CPU by default it is the plain step.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.objectives import LossModule

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
