"""Videos of evaluation rollouts: ``gentlerl video CHECKPOINT -o out.mp4``.

As in the paper's figure of the touch task: each fingertip is coloured by its impact, from yellow
(about 0 N) to red (>= 10 N); the block turns blue on success and black when it breaks (both stand
out against the scene's green background and the yellow-red fingertips). A panel under each frame
shows every fingertip's impact as a bar and a number in N, readable at the default 240 px.
Rendering is offscreen: on a headless machine gentlerl selects ``MUJOCO_GL=osmesa`` itself when
libOSMesa is installed, else ``MUJOCO_GL=egl`` when libEGL loads (``apt-get install libosmesa6``
or ``libegl1``). ``.mp4`` is written
with the ``imageio-ffmpeg`` package (a dependency, it ships its own ffmpeg), ``.gif`` with Pillow.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from tensordict.nn import TensorDictModule
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.apps.outputs import check_output_file
from gentlerl.apps.parsing import command_parser
from gentlerl.envs.assets import FINGERTIPS
from gentlerl.functional import impact
from gentlerl.opengl import INSTALL_HINT, configure_gl

if TYPE_CHECKING:  # the env module imports dm_control, which fixes its backend: see main
    from gentlerl.envs import HandEnv

FULL_RED_AT = 10.0  # N
# Blue and black: the scene's background is green (gymnasium-robotics' skybox) and the fingertips
# run from yellow to red, so neither green nor red would stand out.
BLOCK_RGBA = {"success": (0.1, 0.3, 1.0, 1.0), "broken": (0.05, 0.05, 0.05, 1.0)}
PANEL_BG = (32, 32, 32)
VIDEO_SUFFIXES = (".mp4", ".gif")


def impact_rgba(m: float) -> tuple[float, float, float, float]:
    """Yellow (0 N) to red (>= 10 N), linear in the impact."""
    level = min(max(m / FULL_RED_AT, 0.0), 1.0)
    return (1.0, 1.0 - level, 0.0, 1.0)


def panel_height(size: int) -> int:
    """Rows of the impact panel under a ``size``-pixel frame: >= size / 5, total a multiple of 16.

    Video encoders work on 16-pixel blocks; a frame that is not a multiple is rescaled (blurred).
    """
    return -(-(size + max(size // 5, 24)) // 16) * 16 - size


def draw_impact_panel(
    frame: np.ndarray, impacts: Sequence[float], success: bool = False, broken: bool = False
) -> np.ndarray:
    """``frame`` ``[H, W, 3]`` with a panel appended below: per fingertip a label, a bar filled to
    ``impact / 10 N`` in the fingertip's colour and the impact in N; the outcome, if any, on top.
    """
    from PIL import Image, ImageDraw, ImageFont

    if len(impacts) != len(FINGERTIPS):
        raise ValueError(f"need one impact per fingertip {FINGERTIPS}, got {len(impacts)}")
    height, width = frame.shape[:2]
    rows = panel_height(width)
    font = ImageFont.load_default(size=max(width // 20, 8))
    image = Image.new("RGB", (width, height + rows), PANEL_BG)
    image.paste(Image.fromarray(frame), (0, 0))
    draw = ImageDraw.Draw(image)
    column = width / len(FINGERTIPS)
    bar_top, bar_bottom = height + rows * 0.4, height + rows * 0.62
    for i, (name, m) in enumerate(zip(FINGERTIPS, impacts, strict=True)):
        left, right = i * column + 3, (i + 1) * column - 3
        colour = tuple(int(255 * c) for c in impact_rgba(float(m))[:3])
        fill = left + (right - left) * min(max(float(m) / FULL_RED_AT, 0.0), 1.0)
        draw.rectangle((left, bar_top, right, bar_bottom), outline=(160, 160, 160))
        if fill > left:
            draw.rectangle((left, bar_top, fill, bar_bottom), fill=colour)
        draw.text(((left + right) / 2, height + 2), name, fill="white", font=font, anchor="ma")
        label = f"{float(m):.1f} N"
        draw.text(
            ((left + right) / 2, height + rows - 2), label, fill="white", font=font, anchor="md"
        )
    state = "broken" if broken else "success" if success else None
    if state:
        colour = tuple(int(255 * c) for c in BLOCK_RGBA[state][:3])
        box = draw.textbbox((4, 4), state, font=font)
        draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=colour)
        draw.text((4, 4), state, fill="white", font=font)
    return np.asarray(image)


class ImpactPainter:
    """Colours the fingertip meshes and the block of a hand env's MuJoCo model in place."""

    def __init__(self, env: HandEnv) -> None:
        model = env.dm_env.physics.model
        self.model = model
        self.tips = [model.geom(f"robot0:V_{f}distal").id for f in FINGERTIPS]
        self.block = model.geom("block").id
        self.block_rgba = model.geom_rgba[self.block].copy()
        model.geom_matid[self.tips] = -1  # a material would override geom_rgba
        self.paint(np.zeros(len(self.tips)), success=False, broken=False)

    def paint(self, impacts: np.ndarray, success: bool, broken: bool) -> None:
        for geom, m in zip(self.tips, impacts, strict=True):
            self.model.geom_rgba[geom] = impact_rgba(float(m))
        state = "broken" if broken else "success" if success else None
        self.model.geom_rgba[self.block] = BLOCK_RGBA[state] if state else self.block_rgba


#: A video's most episodes, and most steps per episode (50 s at 20 Hz; the hand's time limit is
#: 200 steps): frames are kept in memory, ~170 KB each at 240 x 240.
MAX_VIDEO_EPISODES, MAX_VIDEO_STEPS = 10, 1_000


@torch.no_grad()
def record_rollouts(
    env: HandEnv,
    actor: TensorDictModule,
    episodes: int = 1,
    size: int = 240,
    hold: int = 10,
    panel: bool = True,
    max_steps: int = MAX_VIDEO_STEPS,
) -> list[np.ndarray]:
    """Frames (uint8 ``[H, W, 3]``) of deterministic rollouts; the last frame is held ``hold`` times.

    With ``panel`` each frame gets :func:`draw_impact_panel` (``H = size + panel_height(size)``).
    An episode the env has not ended after ``max_steps`` steps is cut there.
    """
    painter = ImpactPainter(env)
    frames = []

    def frame(m: np.ndarray, success: bool, broken: bool) -> np.ndarray:
        painter.paint(m, success, broken)
        image = env.render(size, size)
        return draw_impact_panel(image, m, success, broken) if panel else image

    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            td = env.reset()
            frames.append(frame(np.zeros(len(FINGERTIPS)), False, False))
            for _ in range(max_steps):  # the env ends an episode first (limit, success, break)
                td = env.step(actor(td))
                nxt = td["next"]
                m = impact(td[keys.TOUCH], nxt[keys.TOUCH]).numpy()
                frames.append(frame(m, bool(nxt[keys.SUCCESS]), bool(nxt[keys.BROKEN])))
                if nxt[keys.DONE].item():
                    break
                td = nxt
            frames += [frames[-1]] * hold
    return frames


def write_video(frames: Sequence[np.ndarray], path: str | Path, fps: int = 20) -> Path:
    """Write ``.mp4`` (H.264 through imageio-ffmpeg) or ``.gif``, atomically; 20 Hz = control rate.

    MP4 frames are padded to even sizes (H.264's 4:2:0 chroma needs them), never rescaled.
    """
    import imageio.v2 as imageio

    path = check_output_file(path, VIDEO_SUFFIXES)
    if not frames:
        raise ValueError("no frames to write")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        if path.suffix == ".gif":
            imageio.mimsave(tmp, list(frames), duration=1000 / fps, loop=0)
        else:
            height, width = frames[0].shape[:2]
            pad = ((0, height % 2), (0, width % 2), (0, 0))
            even = [np.pad(f, pad, mode="edge") for f in frames]
            imageio.mimsave(tmp, even, fps=fps, macro_block_size=1, quality=8)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def build_parser(prog: str = "gentlerl video") -> argparse.ArgumentParser:
    parser = command_parser(prog, __doc__.splitlines()[0])
    parser.add_argument("checkpoint", help="a run's checkpoint.pt or best_policy.pt")
    parser.add_argument("-o", "--out", default="rollout.mp4", help="output file, .mp4 or .gif")
    parser.add_argument("--episodes", type=int, default=2, help="evaluation episodes to record")
    parser.add_argument("--size", type=int, default=240, help="rendered frame width in pixels")
    parser.add_argument("--seed", type=int, default=0, help="seed of the env (block position)")
    parser.add_argument("--fps", type=int, default=20, help="frames per second (20 = real time)")
    parser.add_argument(
        "--no-panel", action="store_true", help="leave out the per-fingertip impact panel"
    )
    return parser


def main(argv: Sequence[str] | None = None, prog: str = "gentlerl video") -> None:
    """Record a checkpoint's deterministic rollouts to a video file."""
    configure_gl(render=True)  # before dm_control is imported: EGL where OSMesa is absent
    from gentlerl.envs import make_env
    from gentlerl.training.checkpoint import load_policy
    from gentlerl.training.evaluation import check_policy_fits

    args = build_parser(prog).parse_args(argv)
    if not 1 <= args.episodes <= MAX_VIDEO_EPISODES or not 16 <= args.size <= 2048 or args.fps < 1:
        raise SystemExit(
            f"--episodes must be in [1, {MAX_VIDEO_EPISODES}], --size in [16, 2048] and --fps "
            f">= 1, got {args.episodes}, {args.size} and {args.fps}"
        )
    if not 0 <= args.seed < 2**32:
        raise SystemExit(f"--seed must be in [0, 2**32), got {args.seed}")
    check_output_file(args.out, VIDEO_SUFFIXES)  # before the rendering, not after
    if os.environ.get("MUJOCO_GL") == "disable":  # set so by gentlerl.envs: no backend loads
        raise SystemExit(f"{prog}: no OpenGL backend to render with: {INSTALL_HINT}")
    cfg, actor = load_policy(args.checkpoint)
    if cfg.env.name is not None:  # the painter colours the hand's fingertips
        raise SystemExit(f"{prog}: videos show gentlerl's hand; this run trained on {cfg.env.name}")
    env = make_env(cfg.task, seed=args.seed, **cfg.env.kwargs)
    try:
        check_policy_fits(env, actor, args.checkpoint)
        frames = record_rollouts(env, actor, args.episodes, args.size, panel=not args.no_panel)
        print(write_video(frames, args.out, fps=args.fps))
    finally:
        env.close()  # release the GL context before interpreter shutdown
