"""The Shadow Hand gentle-touch environments: dm_control tasks and their TorchRL wrapper."""

from gentlerl.envs.rendering import configure_gl

configure_gl()  # before dm_control is imported

from gentlerl.envs.factory import SUITE, TASKS, make_dm_env, make_env  # noqa: E402
from gentlerl.envs.hand import CALIBRATIONS, Explore, Fragile, HandPhysics, Touch  # noqa: E402
from gentlerl.envs.torchrl_env import HandEnv  # noqa: E402

__all__ = [
    "CALIBRATIONS",
    "SUITE",
    "TASKS",
    "Explore",
    "Fragile",
    "HandEnv",
    "HandPhysics",
    "Touch",
    "make_dm_env",
    "make_env",
]
