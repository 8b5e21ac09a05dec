"""The SAC grid: TorchRL's SAC (``recipes/sac_gentle.py``) with and without gentleness."""
