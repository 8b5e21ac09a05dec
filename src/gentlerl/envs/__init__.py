"""The Shadow Hand gentle-touch environments: dm_control tasks and their TorchRL wrapper.

The OpenGL backend is chosen when this package is first imported, before any of its modules
imports dm_control (:func:`~gentlerl.opengl.configure_gl`: on a headless machine dm_control's
default, GLFW, would print a ``GLFWError``); a ``MUJOCO_GL`` the user set is kept. The names below
are imported on first use (:mod:`gentlerl.lazy`), so that reading the task names imports no MuJoCo.
"""

from gentlerl.lazy import lazy_exports
from gentlerl.opengl import configure_gl

configure_gl()

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.envs.batched": ("BatchedHandEnv",),
        "gentlerl.envs.contacts": ("ContactForces",),
        "gentlerl.envs.driver": ("DriverSpec", "HandDriver", "HandReading"),
        "gentlerl.envs.driver_env": ("DriverHandEnv",),
        "gentlerl.envs.environment": ("HandEnvironment",),
        "gentlerl.envs.external": ("make_external_env",),
        "gentlerl.envs.factory": ("SUITE", "TASK_CLASSES", "TASKS", "make_dm_env", "make_env"),
        "gentlerl.envs.hand": ("REGIMES", "Explore", "Fragile", "HandPhysics", "Touch"),
        "gentlerl.envs.sim_driver": ("BioTacModel", "SimulatedDriver"),
        "gentlerl.envs.task_names": ("TASK_NAMES",),
        "gentlerl.envs.torchrl_env": ("HandEnv",),
        "gentlerl.envs.watchdog": ("ForceWatchdog",),
    },
)
