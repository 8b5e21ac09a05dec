"""``gentlerl video`` checks its output and its OpenGL backend before rendering."""

from __future__ import annotations

import os

import pytest


def test_video_checks_its_output_before_rendering(tmp_path):
    from gentlerl.apps.video import main as video

    missing = str(tmp_path / "no_policy.pt")
    (tmp_path / "dir.mp4").mkdir()
    read_only = tmp_path / "ro"
    read_only.mkdir(mode=0o555)
    cases = [("out.avi", ValueError, "must end in .mp4 or .gif"), ("dir.mp4", OSError, "directory")]
    if os.geteuid() != 0:  # root writes anywhere
        cases.append(("ro/out.mp4", PermissionError, "not writable"))
    for out, error, match in cases:
        with pytest.raises(error, match=match):
            video([missing, "-o", str(tmp_path / out)])
    assert not list(tmp_path.rglob("*.tmp*"))


def test_video_without_an_opengl_backend_says_what_to_install(tmp_path, monkeypatch):
    from gentlerl.apps.video import main as video

    monkeypatch.setenv("MUJOCO_GL", "disable")  # what gentlerl.envs sets when none can load
    with pytest.raises(SystemExit, match="MUJOCO_GL=egl.*apt-get install libosmesa6"):
        video([str(tmp_path / "none.pt"), "-o", str(tmp_path / "v.mp4")])
