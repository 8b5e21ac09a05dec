"""TorchRL ``LossModule`` s: the multi-head D4PG learner and the model (ensemble / ICM) losses."""

from gentlerl.objectives.d4pg import MultiHeadD4PGLoss
from gentlerl.objectives.model_losses import EnsembleModelLoss, ICMLoss, ModelHardUpdate

__all__ = ["EnsembleModelLoss", "ICMLoss", "ModelHardUpdate", "MultiHeadD4PGLoss"]
