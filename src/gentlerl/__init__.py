"""gentlerl: gentle object manipulation with curiosity-driven deep RL, for TorchRL.

Importing it changes nothing in the process: :mod:`gentlerl.envs` chooses dm_control's OpenGL
backend when it is first imported (:func:`gentlerl.opengl.configure_gl`, before dm_control), and
a training run's process set-up records a missing pandas
(:func:`gentlerl.training.builders.prepare_process`).

The public API is each package's ``__all__``; a moved name keeps a deprecated alias for one
release (:mod:`gentlerl.deprecation`).
"""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__``: the installed distribution's version, read on first use (importing
    :mod:`importlib.metadata` at ``import gentlerl`` would load a dozen modules)."""
    if name != "__version__":
        raise AttributeError(f"module 'gentlerl' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("gentlerl")
    except PackageNotFoundError:  # a source tree on sys.path, never installed
        found = "0+unknown"
    globals()["__version__"] = found
    return found
