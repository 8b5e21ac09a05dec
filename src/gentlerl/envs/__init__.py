"""The Shadow Hand gentle-touch environments: dm_control tasks and their TorchRL wrapper.

The OpenGL backend is chosen when ``gentlerl`` is imported, before anything imports dm_control
(:func:`~gentlerl.opengl.configure_gl`); the names below are imported on first use
(:mod:`gentlerl.lazy`), so that reading the task names imports no MuJoCo.
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.envs.batched": ("BatchedHandEnv",),
        "gentlerl.envs.driver": ("DriverSpec", "HandDriver", "HandReading"),
        "gentlerl.envs.driver_env": ("DriverHandEnv",),
        "gentlerl.envs.environment": ("HandEnvironment",),
        "gentlerl.envs.factory": ("SUITE", "TASK_CLASSES", "TASKS", "make_dm_env", "make_env"),
        "gentlerl.envs.hand": ("CALIBRATIONS", "Explore", "Fragile", "HandPhysics", "Touch"),
        "gentlerl.envs.sim_driver": ("BioTacModel", "SimulatedDriver"),
        "gentlerl.envs.task_names": ("TASK_NAMES",),
        "gentlerl.envs.torchrl_env": ("HandEnv",),
        "gentlerl.envs.watchdog": ("ForceWatchdog",),
    },
)
