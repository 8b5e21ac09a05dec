"""The Shadow Hand gentle-touch environments: dm_control tasks and their TorchRL wrapper."""

from gentlerl.envs.rendering import configure_gl

configure_gl()  # before dm_control is imported

from gentlerl.envs.batched import BatchedHandEnv  # noqa: E402
from gentlerl.envs.driver import DriverSpec, HandDriver, HandReading  # noqa: E402
from gentlerl.envs.driver_env import DriverHandEnv  # noqa: E402
from gentlerl.envs.environment import HandEnvironment  # noqa: E402
from gentlerl.envs.factory import SUITE, TASK_CLASSES, TASKS, make_dm_env, make_env  # noqa: E402
from gentlerl.envs.hand import CALIBRATIONS, Explore, Fragile, HandPhysics, Touch  # noqa: E402
from gentlerl.envs.sim_driver import BioTacModel, SimulatedDriver  # noqa: E402
from gentlerl.envs.torchrl_env import HandEnv  # noqa: E402
from gentlerl.envs.watchdog import ForceWatchdog  # noqa: E402

__all__ = [
    "CALIBRATIONS",
    "SUITE",
    "BioTacModel",
    "DriverHandEnv",
    "DriverSpec",
    "ForceWatchdog",
    "HandDriver",
    "HandReading",
    "SimulatedDriver",
    "BatchedHandEnv",
    "TASK_CLASSES",
    "TASKS",
    "Explore",
    "Fragile",
    "HandEnv",
    "HandEnvironment",
    "HandPhysics",
    "Touch",
    "make_dm_env",
    "make_env",
]
