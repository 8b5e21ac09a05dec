"""Training: config, the shared loop (a runner of :mod:`gentlerl.agent`), checkpoints, logging."""

from gentlerl.training.checkpoint import load_checkpoint, load_policy, save_checkpoint
from gentlerl.training.config import TrainConfig, make_config, validate
from gentlerl.training.loop import Trainer, train

__all__ = [
    "TrainConfig",
    "Trainer",
    "load_checkpoint",
    "load_policy",
    "make_config",
    "save_checkpoint",
    "train",
    "validate",
]
