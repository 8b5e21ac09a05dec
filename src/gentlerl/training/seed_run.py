"""What every part of the loop reads of one seed's run: :class:`SeedRun`. Types only, importing
nothing of gentlerl at run time, so that the modules under the loop (its checkpoint checks, its
random streams) can name it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import torch
    from torchrl.data import ReplayBuffer
    from torchrl.data.replay_buffers.scheduler import LinearScheduler

    from gentlerl.agent import AgentBuilder, Learner
    from gentlerl.config.layout import RunLayout
    from gentlerl.data import NStepWriter
    from gentlerl.objectives import MultiHeadD4PGLoss
    from gentlerl.rewards import IntrinsicRewards
    from gentlerl.training.config import TrainConfig


class SeedRun(Protocol):
    """One seed's run as the loop's parts read it (:class:`~gentlerl.training.loop.Trainer` is
    the one implementation): its config and files, its agent's parts, and the state a checkpoint
    keeps. Its :attr:`learner` may train other seeds too: :attr:`seat` is its row."""

    cfg: TrainConfig
    layout: RunLayout
    builder: AgentBuilder
    learner: Learner
    seat: int
    rewards: IntrinsicRewards
    rb: ReplayBuffer
    writer: NStepWriter
    beta_schedule: LinearScheduler | None
    counters: dict[str, Any]
    wall_s: float
    eval_history: list[dict[str, float]]
    best_eval: dict[str, float] | None
    resume_state: dict[str, Any] | None
    rng: dict[str, Any]  # its random streams between its steps (:func:`~.seeding.own_stream`)

    @property
    def policy(self) -> torch.nn.Module: ...  # this seed's acting actor

    @property
    def loss(self) -> MultiHeadD4PGLoss: ...  # this seed's D4PG loss

    def learning(self) -> bool: ...
