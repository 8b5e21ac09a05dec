"""The Shadow Hand touch environment: scene, touch sensing, task logic, bad inputs."""

import numpy as np
import pytest

from gentlerl.envs import TASKS, HandPhysics, make_dm_env
from gentlerl.envs.assets import scene_xml

G = 9.81
FLEX_INDEX_KNUCKLE = 3  # actuator robot0:A_FFJ2


def _press(task: str, *, push: float = 1.0, steps: int = 80, **kwargs):
    """Flex the index knuckle (a constant ``push`` delta) until the episode ends."""
    env = make_dm_env(task, seed=0, **kwargs)
    ts = env.reset()
    action = np.zeros(20)
    action[FLEX_INDEX_KNUCKLE] = push
    touches = [ts.observation["touch"]]
    for _ in range(steps):
        ts = env.step(action)
        touches.append(ts.observation["touch"])
        if ts.last():
            break
    return env, ts, len(touches) - 1, np.stack(touches)


def test_tasks_registry():
    assert TASKS == ("explore", "touch", "fragile")


def test_resting_load_reads_mg_on_the_normal_channel():
    """A 0.2 kg plate resting on the pads of three straight fingers: the normal channels sum to
    m g = 1.962 N (within 5 %). The position-controlled fingers sag a little under the load, so a
    small tangential share (measured ~0.25 N) remains."""
    mass = 0.2
    plate = (
        f'<body name="load" pos="0.989 0.777 0.165"><freejoint/>'
        f'<geom type="box" size="0.03 0.006 0.003" mass="{mass}" contype="1" conaffinity="1"/>'
        "</body></worldbody>"
    )
    physics = HandPhysics.from_xml_string(scene_xml().replace("</worldbody>", plate))
    physics.data.mocap_pos[0] = (1.0, 1.5, 0.5)  # the task block out of the way
    for _ in range(1000):  # 2 s: the plate drops a few mm and settles
        physics.step()
    touch = physics.touch()
    assert touch[:, 0].sum() == pytest.approx(mass * G, rel=0.05)
    assert touch[:3, 0].min() > 0.1  # it rests on the first three fingertips
    assert touch[:, 1:].sum() < 0.15 * mass * G


def test_touch_success_terminates_with_reward_one():
    env, ts, steps, touches = _press("touch", randomize_block=False)
    assert ts.last() and ts.discount == 0.0  # termination, not truncation
    assert ts.reward == 1.0 and env.task.success
    assert touches[-1][:, 0].max() > 5.0  # the first step past the threshold ...
    assert touches[-2][:, 0].max() <= 5.0  # ... and not before
    assert 8 < steps < 16  # the default regime: 0.07 x 1.57 rad per step


def test_actuator_force_is_the_knuckles_effort_of_the_press():
    """Flexing the index knuckle into the block: its actuator exerts < 0.1 N m while it moves
    freely and 0.5-0.6 N m (position error x kp) for the 5 N press (measured 0.085 and 0.61 at
    the default regime, 0.034 and 0.54 at ``easy``)."""
    env, ts, steps, _ = _press("touch", randomize_block=False)
    force = ts.observation["actuator_force"]
    assert force.shape == (20,) and force.dtype == np.float32
    np.testing.assert_allclose(force, env.physics.data.actuator_force, rtol=1e-6)
    assert 0.4 < force[FLEX_INDEX_KNUCKLE] < 0.7
    env.reset()
    action = np.zeros(20)
    action[FLEX_INDEX_KNUCKLE] = 1.0
    for _ in range(steps // 2):  # flexing, not yet touching
        ts = env.step(action)
    assert ts.observation["touch"].sum() == 0.0
    assert 0.0 < ts.observation["actuator_force"][FLEX_INDEX_KNUCKLE] < 0.1


def test_fragile_gentle_press_succeeds_with_reward_five():
    """A quarter-speed knuckle press (0.027 rad per step) ramps the force up gently."""
    env, ts, _, touches = _press("fragile", push=0.25, randomize_block=False)
    impacts = np.clip(np.diff(touches, axis=0), 0, None).sum(-1)  # paper eq. 1, per fingertip
    assert impacts.max() < 3.0
    assert ts.reward == 5.0 and env.task.success and not env.task.broken
    assert ts.discount == 0.0


def test_fragile_full_press_breaks_the_block():
    """The default (``paper``) regime: a full-speed press breaks the fragile block."""
    env, ts, _, touches = _press("fragile", randomize_block=False)
    impacts = np.clip(np.diff(touches, axis=0), 0, None).sum(-1)
    assert impacts[-1].max() > 3.0  # the last step's impact broke it
    assert impacts[:-1].max() <= 3.0
    assert ts.reward == -0.5 and env.task.broken and not env.task.success
    assert ts.discount == 0.0


def test_easy_regime_keeps_the_full_press_gentle():
    """``regime="easy"`` (action scale 0.02): the same full-speed press succeeds."""
    env, ts, steps, touches = _press("fragile", randomize_block=False, regime="easy")
    impacts = np.clip(np.diff(touches, axis=0), 0, None).sum(-1)
    assert env.task.action_scale == 0.02 and impacts.max() < 1.5
    assert ts.reward == 5.0 and env.task.success and 20 < steps < 60


def test_regime_values_and_overrides():
    gain = {
        n: make_dm_env("touch", regime=n).physics.model.actuator_gainprm[3, 0]
        for n in ("paper", "easy")
    }
    assert gain == {"paper": 3.0, "easy": 3.0}
    env = make_dm_env("touch", regime="easy", action_scale=0.1, actuator_gain=5.0)
    assert env.task.action_scale == 0.1 and env.physics.model.actuator_gainprm[3, 0] == 5.0
    near, far = (
        make_dm_env("touch", randomize_block=False, block_gap=gap).task.block_pos
        for gap in (0, 0.01)
    )
    np.testing.assert_allclose(far - near, [0.0, 0.01 * np.sin(0.75), 0.01 * np.cos(0.75)])


def test_explore_has_no_reward_and_truncates():
    env = make_dm_env("explore", seed=0, time_limit=7)
    ts = env.reset()
    rewards = []
    for _ in range(7):
        ts = env.step(np.ones(20))
        rewards.append(ts.reward)
    assert rewards == [0.0] * 7
    assert ts.last() and ts.discount == 1.0  # truncation keeps the bootstrap


def test_block_randomisation_is_small_and_seeded():
    def block(seed, **kw):
        env = make_dm_env("touch", seed=seed, **kw)
        env.reset()
        return env.physics.data.mocap_pos[0].copy()

    fixed = block(0, randomize_block=False)
    a, b, c = block(1), block(1), block(2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.abs(a - fixed).max() <= 0.005 and a[2] == fixed[2]


def test_the_regimes_earlier_keyword_is_refused_naming_the_new_one():
    with pytest.raises(
        TypeError, match=r"^calibration= is now regime= \(the hand's physics regime\)$"
    ):
        make_dm_env("touch", calibration="easy")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"task": "grasp"}, "unknown task 'grasp'"),
        ({"force_threshold": -1.0}, "force_threshold must be a finite number >= 0, got -1.0"),
        ({"task": "fragile", "break_impact": -3.0}, "break_impact must be .* got -3.0"),
        ({"block_range": float("nan")}, "block_range"),
        ({"action_scale": 0.0}, r"action_scale must be in \(0, 1\], got 0.0"),
        ({"time_limit": 0}, "time_limit must be an integer >= 1"),
        ({"regime": "hard"}, "unknown regime 'hard'; expected one of"),
        ({"actuator_gain": 0.0}, "actuator_gain must be a finite number > 0, got 0.0"),
        ({"block_gap": 0.2}, r"block_gap must be in \[-0.01, 0.05\] m, got 0.2"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_dm_env(**kwargs)


def test_bad_actions():
    env = make_dm_env("touch", seed=0)
    env.reset()
    with pytest.raises(ValueError, match=r"action must have shape \(20,\), got \(19,\)"):
        env.step(np.zeros(19))
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(np.full(20, np.nan))


def test_contacts_are_looked_up_only_for_an_outcome_rule(monkeypatch):
    """Explore has no outcome rule, so its steps skip the fingertip-contact look-up; an Explore
    subclass with its own ``update_outcome`` gets the contacts of the press (index fingertip)."""
    from gentlerl.envs.hand import Explore

    calls, real = [], HandPhysics.block_contact
    monkeypatch.setattr(HandPhysics, "block_contact", lambda self: calls.append(1) or real(self))
    _press("explore", steps=40)
    assert calls == []

    class Judged(Explore):
        def update_outcome(self, touch, previous, on_block):
            self.success = bool(on_block[0])  # the index fingertip (ff)

    env = make_dm_env("explore", seed=0)
    env._task = Judged()
    env.reset()
    action = np.zeros(20)
    action[FLEX_INDEX_KNUCKLE] = 1.0
    steps = 0
    while not env.task.success and steps < 40:
        env.step(action)
        steps += 1
    assert env.task.success and 0 < len(calls) <= steps
