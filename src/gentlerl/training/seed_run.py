"""What a checkpoint's checks read of one seed's run: :class:`SeedRun`. Types only, importing
nothing of gentlerl at run time, so that :mod:`~gentlerl.training.checkpoint_schema`, which the
loop imports, can name it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from torchrl.data.replay_buffers.scheduler import LinearScheduler

    from gentlerl.agent import Learner
    from gentlerl.objectives import MultiHeadD4PGLoss
    from gentlerl.rewards import IntrinsicRewards


class SeedRun(Protocol):
    """One seed's run as a checkpoint's checks read it (:class:`~gentlerl.training.loop.Trainer`
    is the one implementation): the networks and optimisers a checkpoint restores. Its
    :attr:`learner` may train other seeds too."""

    learner: Learner
    rewards: IntrinsicRewards
    beta_schedule: LinearScheduler | None

    @property
    def loss(self) -> MultiHeadD4PGLoss: ...  # this seed's D4PG loss
