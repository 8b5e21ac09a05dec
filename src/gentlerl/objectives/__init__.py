"""TorchRL ``LossModule`` s: the multi-head D4PG learner and the model (ensemble / ICM) losses."""

from gentlerl.objectives.d4pg import MultiHeadD4PGLoss

__all__ = ["MultiHeadD4PGLoss"]
