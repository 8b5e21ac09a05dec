"""Test-session settings."""

import torch

# One thread: on the 2-core CI machine, two torch threads contend with the env and with
# collector / ParallelEnv worker processes and made the model-training tests ~20x slower.
torch.set_num_threads(1)
