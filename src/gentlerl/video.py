"""Videos of evaluation rollouts: ``python -m gentlerl.video CHECKPOINT -o out.mp4``.

As in the paper's figure of the touch task: each fingertip is coloured by its impact, from yellow
(about 0 N) to red (>= 10 N), and the block turns green on success and red when it breaks.
Rendering is offscreen and needs OSMesa (``apt-get install libosmesa6``; gentlerl selects
``MUJOCO_GL=osmesa`` itself on a headless machine when the library is there). ``.mp4`` needs the
``imageio-ffmpeg`` package; ``.gif`` works with the installed Pillow.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from tensordict.nn import TensorDictModule
from torchrl.envs.utils import ExplorationType, set_exploration_type

from gentlerl import keys
from gentlerl.envs import HandEnv, make_env
from gentlerl.envs.assets import FINGERTIPS
from gentlerl.functional import impact

FULL_RED_AT = 10.0  # N
BLOCK_RGBA = {"success": (0.2, 0.8, 0.2, 1.0), "broken": (0.9, 0.1, 0.1, 1.0)}


def impact_rgba(m: float) -> tuple[float, float, float, float]:
    """Yellow (0 N) to red (>= 10 N), linear in the impact."""
    level = min(max(m / FULL_RED_AT, 0.0), 1.0)
    return (1.0, 1.0 - level, 0.0, 1.0)


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


@torch.no_grad()
def record_rollouts(
    env: HandEnv, actor: TensorDictModule, episodes: int = 1, size: int = 240, hold: int = 10
) -> list[np.ndarray]:
    """Frames (uint8 [H, W, 3]) of deterministic rollouts; the last frame is held ``hold`` times."""
    painter = ImpactPainter(env)
    frames = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            td = env.reset()
            painter.paint(np.zeros(len(FINGERTIPS)), False, False)
            frames.append(env.render(size, size))
            while True:  # the env ends every episode (time limit, success or break)
                td = env.step(actor(td))
                nxt = td["next"]
                m = impact(td[keys.TOUCH], nxt[keys.TOUCH]).numpy()
                painter.paint(m, bool(nxt[keys.SUCCESS]), bool(nxt[keys.BROKEN]))
                frames.append(env.render(size, size))
                if nxt[keys.DONE].item():
                    break
                td = nxt
            frames += [frames[-1]] * hold
    return frames


def write_video(frames: Sequence[np.ndarray], path: str | Path, fps: int = 20) -> Path:
    """Write ``.mp4`` (needs imageio-ffmpeg) or ``.gif``; the control rate is 20 Hz."""
    import imageio.v2 as imageio

    path = Path(path)
    if path.suffix not in (".mp4", ".gif"):
        raise ValueError(f"video path must end in .mp4 or .gif, got {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".gif":
        imageio.mimsave(path, list(frames), duration=1000 / fps, loop=0)
    else:
        try:
            imageio.mimsave(path, list(frames), fps=fps)
        except (ImportError, ValueError) as err:
            raise RuntimeError(
                f"writing {path} needs `pip install imageio-ffmpeg` (or use .gif)"
            ) from err
    return path


def main(argv: Sequence[str] | None = None) -> None:
    from gentlerl.training.checkpoint import load_policy

    parser = argparse.ArgumentParser(
        prog="python -m gentlerl.video", description=__doc__.splitlines()[0]
    )
    parser.add_argument("checkpoint", help="a run's checkpoint.pt or best_policy.pt")
    parser.add_argument("-o", "--out", default="rollout.gif", help=".mp4 or .gif")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--size", type=int, default=240)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    cfg, actor = load_policy(args.checkpoint)
    env = make_env(cfg.task, seed=args.seed, **cfg.env_kwargs)
    try:
        print(write_video(record_rollouts(env, actor, args.episodes, args.size), args.out))
    finally:
        env.dm_env.physics.free()  # release the GL context before interpreter shutdown


if __name__ == "__main__":
    main()
