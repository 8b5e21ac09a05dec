"""Video colouring (no GL needed) and, where OSMesa is installed, real offscreen frames."""

import ctypes.util

import numpy as np
import pytest
import torch
from tensordict.nn import TensorDictModule

from gentlerl.apps.video import (
    BLOCK_RGBA,
    FULL_RED_AT,
    ImpactPainter,
    draw_impact_panel,
    impact_rgba,
    main,
    panel_height,
    record_rollouts,
    write_video,
)
from gentlerl.envs import make_env

needs_osmesa = pytest.mark.skipif(
    ctypes.util.find_library("OSMesa") is None, reason="needs libosmesa6"
)


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


def test_mp4_is_written_and_reads_back_with_its_frame_count(tmp_path):
    import imageio.v2 as imageio

    # 33 frames of an odd-sized (75 x 63) gradient: padded to 76 x 64, never rescaled.
    frames = [np.full((75, 63, 3), 7 * i, dtype=np.uint8) for i in range(33)]
    path = write_video(frames, tmp_path / "clip.mp4", fps=20)
    reader = imageio.get_reader(path)
    try:
        assert reader.count_frames() == 33
        assert reader.get_meta_data()["fps"] == 20
        first = reader.get_data(0)
    finally:
        reader.close()
    assert first.shape == (76, 64, 3)
    assert abs(int(first[30, 30, 0]) - 0) <= 3  # frame 0 is black, ~lossless on flat colour
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


def test_impact_panel_bars_are_filled_in_proportion_to_the_impact():
    impacts = [0.0, 5.0, FULL_RED_AT, 20.0, 2.5]
    frame = draw_impact_panel(np.zeros((240, 240, 3), np.uint8), impacts)
    rows = panel_height(240)
    assert rows == 48 and frame.shape == (240 + rows, 240, 3)  # 288 = 18 x 16
    assert not frame[:240].any()  # the rendered frame is untouched
    bar_row = frame[240 + int(rows * 0.5)]
    for i, m in enumerate(impacts):
        colour = np.array(impact_rgba(m)[:3]) * 255
        column = bar_row[i * 48 : (i + 1) * 48].astype(float)
        filled = (np.abs(column - colour).sum(-1) < 10).sum()
        expected = 42 * min(m / FULL_RED_AT, 1.0)  # 48-px column, 3 px margin each side
        assert abs(filled - expected) <= 2, (m, filled, expected)
    with pytest.raises(ValueError, match="one impact per fingertip"):
        draw_impact_panel(np.zeros((64, 64, 3), np.uint8), [1.0, 2.0])


def test_video_help_lists_every_option_with_its_default(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option in ("--episodes", "--size", "--seed", "--fps", "--no-panel"):
        assert option in text
    assert "(default: rollout.mp4)" in text and "(default: 240)" in text


@needs_osmesa
def test_scripted_press_renders_and_colours_the_block_against_the_background(tmp_path):
    press = torch.zeros(20)
    press[3] = 1.0  # flex the index knuckle: succeeds in about 38 steps
    actor = TensorDictModule(
        lambda obs: press.expand(*obs.shape[:-1], 20), ["observation"], ["action"]
    )
    env = make_env("touch", seed=0, randomize_block=False, regime="easy")
    try:
        frames = record_rollouts(env, actor, episodes=1, size=64, hold=2)
        model = env.dm_env.physics.model
        np.testing.assert_allclose(model.geom_rgba[model.geom("block").id], BLOCK_RGBA["success"])
        assert 30 < len(frames) < 60 and frames[0].shape == (64 + panel_height(64), 64, 3)
        path = write_video(frames, tmp_path / "press.gif")
        assert path.stat().st_size > 1000
        # The outcome colours stand out from the background (a corner of the rendered scene)
        # and from every impact colour (yellow to red): RGB distance > 0.5 of full scale.
        background = env.render(64, 64)[0, 0] / 255
        impact_colours = [np.array(impact_rgba(m)[:3]) for m in np.linspace(0, FULL_RED_AT, 11)]
        for rgba in BLOCK_RGBA.values():
            block = np.array(rgba[:3])
            assert np.linalg.norm(block - background) > 0.5, (rgba, background)
            assert min(np.linalg.norm(block - c) for c in impact_colours) > 0.5
    finally:
        env.close()
    with pytest.raises(ValueError, match=r"\.mp4 or \.gif"):
        write_video(frames, tmp_path / "press.avi")
