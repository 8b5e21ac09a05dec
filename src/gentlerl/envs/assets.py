"""The Shadow Hand scene: gymnasium-robotics' MJCF (loaded from the installed package), a block,
and MuJoCo's ``touch_grid`` plugin on the five fingertip touch sites. Nothing is downloaded."""

from __future__ import annotations

import importlib.util
import re
from functools import cache
from pathlib import Path

FINGERTIPS = ("ff", "mf", "rf", "lf", "th")
TOUCH_SITES = tuple(f"robot0:Tch_{f}tip" for f in FINGERTIPS)
GRID = (4, 4)
CHANNELS = 3

# The touch_grid plugin senses contacts along its site's -z axis. The gymnasium sites are
# axis-aligned with the distal phalanx, whose pad faces -y (fingers) or -x (thumb); these
# rotations point each site's -z out of the pad.
_FINGER_PAD_QUAT = "0.70710678 -0.70710678 0 0"
_THUMB_PAD_QUAT = "0.70710678 0 0.70710678 0"
# The block is a plate tilted by 0.75 rad about x: its lower face lies flat on the distal pads of
# the first three fingers when their knuckles (J2) are flexed by 0.75 rad, so flexing a knuckle
# further presses the pad straight into it (contact inside the touch grid's field of view).
BLOCK_QUAT = "0.930508 -0.366271 0 0"


def hand_asset_dir() -> Path:
    """``gymnasium_robotics/envs/assets/hand`` of the installed package.

    Found without importing it (its import registers every gymnasium env and prints warnings).
    """
    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or not spec.submodule_search_locations:  # pragma: no cover - a dependency
        raise ImportError(
            "gentlerl needs the Shadow Hand model shipped in gymnasium-robotics: "
            "pip install gymnasium-robotics"
        )
    path = Path(spec.submodule_search_locations[0]) / "envs" / "assets" / "hand"
    if not (path / "robot.xml").is_file():
        raise FileNotFoundError(f"the Shadow Hand MJCF was not found under {path}")
    return path


def _body(xml: str) -> str:
    """The children of a file's top-level ``<mujoco>`` element."""
    xml = re.sub(r"<!--.*?-->", "", xml, flags=re.S)
    return xml.split("<mujoco>", 1)[1].rsplit("</mujoco>", 1)[0]


def _orient_touch_sites(robot: str) -> str:
    for name in TOUCH_SITES:
        quat = _THUMB_PAD_QUAT if name.endswith("thtip") else _FINGER_PAD_QUAT
        robot = re.sub(
            rf'(<site class="robot0:D_Touch" name="{re.escape(name)}")',
            rf'\1 quat="{quat}"',
            robot,
        )
    return robot


def _strengthen_fingers(shared: str, gain: float) -> str:
    """Scale kp and force range of the finger and thumb position actuators by ``gain``.

    With gymnasium-robotics' values (kp = 1, |torque| <= 0.9 N m) a fully flexed finger presses a
    block with barely 5 N, the touch task's success threshold; a gain of 3 gives the headroom
    the task needs (about 15 N) while keeping the hand compliant. The wrist is left as it is.
    """

    def scale(match: re.Match) -> str:
        tag = match.group(0)
        if 'name="robot0:A_WRJ' in tag:
            return tag
        kp = float(re.search(r'kp="([^"]+)"', tag).group(1))
        lo, hi = (float(v) for v in re.search(r'forcerange="([^"]+)"', tag).group(1).split())
        tag = re.sub(r'kp="[^"]+"', f'kp="{kp * gain:g}"', tag)
        return re.sub(r'forcerange="[^"]+"', f'forcerange="{lo * gain:g} {hi * gain:g}"', tag)

    return re.sub(r"<position [^>]*>", scale, shared)


def _touch_grid_sensors(fov_deg: float) -> str:
    sensors = []
    for name in TOUCH_SITES:
        sensors.append(
            f'<plugin name="{name.replace("Tch", "TG")}" plugin="mujoco.sensor.touch_grid" '
            f'objtype="site" objname="{name}">'
            f'<config key="nchannel" value="{CHANNELS}"/>'
            f'<config key="size" value="{GRID[0]} {GRID[1]}"/>'
            f'<config key="fov" value="{fov_deg} {fov_deg}"/>'
            '<config key="gamma" value="0"/></plugin>'
        )
    return "<sensor>" + "".join(sensors) + "</sensor>"


@cache
def scene_xml(fov_deg: float = 90.0, actuator_gain: float = 3.0) -> str:
    """MJCF of the hand (palm up, as in gymnasium-robotics) with a fixed block over its fingers.

    The block is a mocap body, so the task can move it (randomisation) while contacts cannot.
    """
    assets = hand_asset_dir()
    shared = _strengthen_fingers(_body((assets / "shared.xml").read_text()), actuator_gain)
    shared_asset = _body((assets / "shared_asset.xml").read_text())
    robot = _orient_touch_sites(_body((assets / "robot.xml").read_text()))
    meshdir = (assets / ".." / "stls" / "hand").resolve()
    texturedir = (assets / ".." / "textures").resolve()
    return f"""<mujoco model="gentlerl_hand">
  <compiler angle="radian" coordinate="local" meshdir="{meshdir}" texturedir="{texturedir}"/>
  <option timestep="0.002" iterations="20"><flag warmstart="enable"/></option>
  <extension><plugin plugin="mujoco.sensor.touch_grid"/></extension>
  {shared}
  <asset>{shared_asset}</asset>
  <worldbody>
    <light directional="true" ambient="0.2 0.2 0.2" diffuse="0.8 0.8 0.8" pos="0 0 4" dir="0 0 -1"/>
    <camera name="side" pos="1.0 0.55 0.40" xyaxes="1 0 0 0 0.6 0.8" fovy="45"/>
    {robot}
    <body name="block" mocap="true" pos="1 0.8124 0.2111" quat="{BLOCK_QUAT}">
      <geom name="block" type="box" size="0.045 0.012 0.01" rgba="0.9 0.7 0.3 1"
            contype="1" conaffinity="1" friction="1 0.005 0.001"/>
    </body>
  </worldbody>
  {_touch_grid_sensors(fov_deg)}
</mujoco>"""
