"""Optional offscreen rendering. Nothing else in gentlerl needs OpenGL.

dm_control picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported, and a backend
that cannot load (e.g. ``MUJOCO_GL=osmesa`` without libOSMesa) crashes that import deep inside
PyOpenGL. :func:`configure_gl` runs before dm_control is imported: on a headless machine it picks
OSMesa when the library is installed, and otherwise disables rendering so that everything else
works; :func:`render` turns a missing backend into an error that says what to install.

It also turns off dm_control's render-thread offloading (``DISABLE_RENDER_THREAD_OFFLOADING``,
unless the user set it). With offloading, a GL context freed by the cyclic garbage collector hangs
the process: the collector clears the weakref that keeps the context's worker thread alive, the
thread exits, and the context's ``__del__`` then waits forever on a job no thread will run.
Rendering on the calling thread has no such job, and gentlerl renders from one thread only.
"""

from __future__ import annotations

import ctypes.util
import os
import warnings

import numpy as np

INSTALL_HINT = (
    "offscreen rendering needs EGL or OSMesa: run with `MUJOCO_GL=egl` (libEGL, e.g. "
    "`apt-get install libegl1`), or `apt-get install libosmesa6` and run with "
    "`MUJOCO_GL=osmesa PYOPENGL_PLATFORM=osmesa`"
)


def configure_gl() -> None:
    """Choose dm_control's OpenGL backend before it is imported (see module docstring)."""
    os.environ.setdefault("DISABLE_RENDER_THREAD_OFFLOADING", "1")
    backend = os.environ.get("MUJOCO_GL")
    has_osmesa = ctypes.util.find_library("OSMesa") is not None
    if backend is None and not os.environ.get("DISPLAY"):
        backend = "osmesa" if has_osmesa else "disable"
        os.environ["MUJOCO_GL"] = backend
    if backend == "osmesa":
        if has_osmesa:
            os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
        else:
            warnings.warn(
                f"MUJOCO_GL=osmesa but libOSMesa is missing; rendering is off ({INSTALL_HINT})",
                stacklevel=2,
            )
            os.environ["MUJOCO_GL"] = "disable"


def render(physics: object, height: int, width: int, camera_id: int | str = 0) -> np.ndarray:
    """``physics.render`` as ``uint8 [H, W, 3]``, or a ``RuntimeError`` saying what to install."""
    if height < 1 or width < 1:
        raise ValueError(f"render size must be positive, got {height}x{width}")
    try:
        frame = physics.render(height=height, width=width, camera_id=camera_id)
    except RuntimeError as err:
        if "No OpenGL rendering backend" in str(err):
            raise RuntimeError(f"no OpenGL backend to render with: {INSTALL_HINT}") from err
        raise
    return np.ascontiguousarray(frame)  # dm_control flips rows with a negative-stride view
