"""Offscreen frames of a hand env's physics; the OpenGL backend is chosen by
:func:`gentlerl.opengl.configure_gl` when :mod:`gentlerl.envs` is imported."""

from __future__ import annotations

import numpy as np

from gentlerl.opengl import INSTALL_HINT


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
