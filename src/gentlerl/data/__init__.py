"""Replay buffers: prioritised n-step replay for the learner, uniform 1-step replay for models."""

from gentlerl.data.prioritized import FlatPriorityTree, TorchPrioritizedSampler
from gentlerl.data.replay import (
    NStepTerminated,
    NStepWriter,
    make_beta_scheduler,
    make_model_buffer,
    make_nstep_transform,
    make_replay_buffer,
)
from gentlerl.data.windows import (
    WINDOW,
    contact_step_sum,
    nstep_return,
    nstep_windows,
    rescore_windows,
    window_of,
)

__all__ = [
    "FlatPriorityTree",
    "TorchPrioritizedSampler",
    "NStepTerminated",
    "NStepWriter",
    "contact_step_sum",
    "make_beta_scheduler",
    "make_model_buffer",
    "make_nstep_transform",
    "make_replay_buffer",
    "nstep_return",
    "nstep_windows",
    "rescore_windows",
    "window_of",
    "WINDOW",
]
