"""gentlerl: gentle object manipulation with curiosity-driven deep RL, for TorchRL."""

__version__ = "0.1.0"
