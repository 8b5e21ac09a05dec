"""Which OpenGL backend gentlerl picks for dm_control, and ``gentlerl video`` with what is there.

The choice logic runs on mocks (which libraries exist and load, whether a display is set, whether
dm_control was imported); the end-to-end check renders with EGL where the machine has it.
"""

import ctypes
import ctypes.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gentlerl import opengl
from tests.apps.test_evaluate import _scripted_policy

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("has_osmesa", "egl_loads", "backend"),
    [(True, True, "osmesa"), (True, False, "osmesa"), (False, True, "egl"), (False, False, "disable")],
)  # fmt: skip
def test_headless_backend_prefers_osmesa_then_egl(has_osmesa, egl_loads, backend):
    assert opengl.headless_backend(has_osmesa, egl_loads) == backend


@pytest.fixture
def headless(monkeypatch):
    """A machine without a display, MUJOCO_GL unset, dm_control not imported yet; ``libs`` names
    the libraries ``ctypes`` finds (``{"EGL": "libEGL.so.1"}``) and ``loads`` whether they open."""
    libs: dict[str, str] = {}
    opened: list[str] = []
    loads = {"ok": True}

    def cdll(name, *args, **kwargs):
        opened.append(name)
        if not loads["ok"]:
            raise OSError(f"{name}: cannot open shared object file")
        return object()

    for var in ("DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.delitem(sys.modules, "dm_control._render", raising=False)
    monkeypatch.setattr(opengl, "_chosen", None)
    monkeypatch.setattr(ctypes.util, "find_library", libs.get)
    monkeypatch.setattr(ctypes, "CDLL", cdll)
    return libs, opened, loads


def test_a_run_that_does_not_render_leaves_egl_closed(headless):
    libs, opened, _ = headless
    libs["EGL"] = "libEGL.so.1"
    opengl.configure_gl()
    assert os.environ["MUJOCO_GL"] == "disable" and opened == []  # EGL costs 0.5 s per process


def test_rendering_picks_egl_when_osmesa_is_absent_and_egl_loads(headless):
    libs, opened, _ = headless
    libs["EGL"] = "libEGL.so.1"
    opengl.configure_gl()  # at `import gentlerl`
    opengl.configure_gl(render=True)  # `gentlerl video`, before dm_control is imported
    assert os.environ["MUJOCO_GL"] == "egl" and opened == ["libEGL.so.1"]
    assert "PYOPENGL_PLATFORM" not in os.environ  # dm_control's EGL renderer sets it itself


def test_rendering_prefers_osmesa_where_it_is_installed(headless):
    libs, opened, _ = headless
    libs.update(OSMesa="libOSMesa.so.8", EGL="libEGL.so.1")
    opengl.configure_gl(render=True)
    assert os.environ["MUJOCO_GL"] == os.environ["PYOPENGL_PLATFORM"] == "osmesa"
    assert opened == []


@pytest.mark.parametrize("libegl", [None, "libEGL.so.1"])
def test_rendering_is_off_when_egl_is_missing_or_does_not_load(headless, libegl):
    libs, _, loads = headless
    if libegl:
        libs["EGL"] = libegl
        loads["ok"] = False
    opengl.configure_gl(render=True)
    assert os.environ["MUJOCO_GL"] == "disable"


def test_a_backend_the_user_set_or_dm_control_already_uses_is_kept(headless, monkeypatch):
    libs, opened, _ = headless
    libs["EGL"] = "libEGL.so.1"
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    opengl.configure_gl(render=True)
    assert os.environ["MUJOCO_GL"] == "glfw"
    monkeypatch.delenv("MUJOCO_GL")
    opengl.configure_gl()
    monkeypatch.setitem(sys.modules, "dm_control._render", object())  # its backend is fixed
    opengl.configure_gl(render=True)
    assert os.environ["MUJOCO_GL"] == "disable" and opened == []


def test_a_display_leaves_the_choice_to_dm_control(headless, monkeypatch):
    headless[0]["EGL"] = "libEGL.so.1"
    monkeypatch.setenv("DISPLAY", ":0")
    opengl.configure_gl(render=True)
    assert "MUJOCO_GL" not in os.environ


@pytest.mark.skipif(
    ctypes.util.find_library("OSMesa") is not None or not opengl.egl_loads(),
    reason="needs libEGL without libOSMesa",
)
def test_video_renders_with_egl_when_mujoco_gl_is_unset(tmp_path):
    policy = _scripted_policy(tmp_path / "policy.pt", push=0.3, task="touch")
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env = {**env, "PYTHONPATH": str(ROOT / "src")}
    env.pop("DISPLAY", None)
    out = tmp_path / "press.mp4"
    command = [sys.executable, "-m", "gentlerl", "video", str(policy), "-o", str(out)]
    done = subprocess.run(
        [*command, "--episodes", "1", "--size", "32"],
        env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr

    import imageio.v2 as imageio

    reader = imageio.get_reader(out)
    try:
        frames = reader.count_frames()
        mean = reader.get_data(0).mean()
    finally:
        reader.close()
    assert frames >= 10  # one episode and the held last frame
    assert mean > 20  # a rendered scene, not the black frames of a failed context
