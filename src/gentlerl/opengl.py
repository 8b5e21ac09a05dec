"""dm_control's OpenGL backend, chosen when gentlerl.envs is imported (optional offscreen rendering;
nothing else in gentlerl needs OpenGL). Imports nothing of gentlerl.

dm_control picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported, and a backend
that cannot load (e.g. ``MUJOCO_GL=osmesa`` without libOSMesa) crashes that import deep inside
PyOpenGL; left unset on a headless machine, it tries GLFW first, which prints ``GLFWError: ...
The DISPLAY environment variable is missing``. :func:`configure_gl` runs when gentlerl.envs
is imported, before dm_control: on a headless machine it picks OSMesa when the library is
installed; for a command that renders (``gentlerl video``) EGL when OSMesa is absent and libEGL
loads (dm_control opens an EGL display when it is imported, 0.5 s per process, so a training run
does not); and otherwise disables rendering so that everything else works.
:func:`gentlerl.envs.rendering.render` turns a missing backend into an error that says what to
install.

It also turns off dm_control's render-thread offloading (``DISABLE_RENDER_THREAD_OFFLOADING``,
unless the user set it). With offloading, a GL context freed by the cyclic garbage collector hangs
the process: the collector clears the weakref that keeps the context's worker thread alive, the
thread exits, and the context's ``__del__`` then waits forever on a job no thread will run.
Rendering on the calling thread has no such job, and gentlerl renders from one thread only.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import warnings

INSTALL_HINT = (
    "offscreen rendering needs EGL or OSMesa: run with `MUJOCO_GL=egl` (libEGL, e.g. "
    "`apt-get install libegl1`), or `apt-get install libosmesa6` and run with "
    "`MUJOCO_GL=osmesa PYOPENGL_PLATFORM=osmesa`"
)


#: The backend :func:`configure_gl` chose itself (``MUJOCO_GL`` was unset), if any.
_chosen: str | None = None


def headless_backend(has_osmesa: bool, egl_loads: bool) -> str:
    """``MUJOCO_GL`` for a machine without a display: OSMesa when installed, else EGL when it
    loads (``egl_loads`` is only probed for a command that renders), else ``disable``."""
    if has_osmesa:
        return "osmesa"
    return "egl" if egl_loads else "disable"


def egl_loads() -> bool:
    """Whether libEGL is installed and loads (``ctypes`` finds and opens it)."""
    name = ctypes.util.find_library("EGL")
    if name is None:
        return False
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def configure_gl(render: bool = False) -> None:
    """Choose dm_control's OpenGL backend before it is imported (see module docstring).

    ``render``: the caller is about to render, so EGL is worth its start-up cost; called so
    before dm_control is imported, it revisits the choice it made itself without ``render``.
    A ``MUJOCO_GL`` the user set is kept.
    """
    global _chosen
    os.environ.setdefault("DISABLE_RENDER_THREAD_OFFLOADING", "1")
    backend = os.environ.get("MUJOCO_GL")
    has_osmesa = ctypes.util.find_library("OSMesa") is not None
    ours = backend is not None and backend == _chosen and "dm_control._render" not in sys.modules
    if (backend is None or ours) and not os.environ.get("DISPLAY"):
        egl = render and not has_osmesa and egl_loads()  # opened only where it would be used
        backend = _chosen = headless_backend(has_osmesa, egl)
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
