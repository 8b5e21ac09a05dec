"""Video colouring (no GL needed) and, where OSMesa is installed, real offscreen frames."""

import ctypes.util

import numpy as np
import pytest
import torch
from tensordict.nn import TensorDictModule

from gentlerl.envs import make_env
from gentlerl.video import BLOCK_RGBA, ImpactPainter, impact_rgba, record_rollouts, write_video


def test_impact_colours_go_from_yellow_to_red_at_10_newtons():
    assert impact_rgba(0.0) == (1.0, 1.0, 0.0, 1.0)
    assert impact_rgba(5.0) == (1.0, 0.5, 0.0, 1.0)
    assert impact_rgba(10.0) == impact_rgba(25.0) == (1.0, 0.0, 0.0, 1.0)


def test_painter_colours_fingertips_and_block_in_the_model():
    env = make_env("touch", seed=0)
    painter = ImpactPainter(env)
    rgba = env.dm_env.physics.model.geom_rgba
    painter.paint(np.array([0.0, 10.0, 5.0, 0.0, 0.0]), success=True, broken=False)
    assert tuple(rgba[painter.tips[1]]) == (1.0, 0.0, 0.0, 1.0)
    assert tuple(rgba[painter.tips[2]]) == (1.0, 0.5, 0.0, 1.0)
    np.testing.assert_allclose(rgba[painter.block], BLOCK_RGBA["success"])
    painter.paint(np.zeros(5), success=False, broken=True)
    np.testing.assert_allclose(rgba[painter.block], BLOCK_RGBA["broken"])


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is None, reason="needs libosmesa6")
def test_scripted_press_renders_and_turns_the_block_green(tmp_path):
    press = torch.zeros(20)
    press[3] = 1.0  # flex the index knuckle: succeeds in about 38 steps
    actor = TensorDictModule(
        lambda obs: press.expand(*obs.shape[:-1], 20), ["observation"], ["action"]
    )
    env = make_env("touch", seed=0, randomize_block=False)
    try:
        frames = record_rollouts(env, actor, episodes=1, size=64, hold=2)
        model = env.dm_env.physics.model
        np.testing.assert_allclose(model.geom_rgba[model.geom("block").id], BLOCK_RGBA["success"])
        assert 30 < len(frames) < 60 and frames[0].shape == (64, 64, 3)
        path = write_video(frames, tmp_path / "press.gif")
        assert path.stat().st_size > 1000
    finally:
        env.dm_env.physics.free()
    with pytest.raises(ValueError, match=r"\.mp4 or \.gif"):
        write_video(frames, tmp_path / "press.avi")
