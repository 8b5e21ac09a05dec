"""The TorchRL view of the hand env: specs, keys, determinism, done flags, rendering errors."""

import ctypes.util
import gc
import os
import subprocess
import sys

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.envs import TASKS, make_env


def _policy(seed: int):
    generator = torch.Generator().manual_seed(seed)

    def act(td):
        return td.set(keys.ACTION, torch.rand(20, generator=generator) * 2 - 1)

    return act


@pytest.mark.parametrize("task", TASKS)
def test_check_env_specs(task, hand_env):
    check_env_specs(hand_env(task, seed=0))


def test_observation_shapes_dtypes_and_flat_observation(hand_env):
    env = hand_env("fragile", seed=0)
    td = env.rollout(4, _policy(0))
    shapes = {
        keys.JOINT_POS: (4, 24),
        keys.JOINT_VEL: (4, 24),
        keys.TOUCH: (4, 5, 3),
        keys.TOUCH_GRID: (4, 5, 3, 4, 4),
        keys.ACTUATOR_FORCE: (4, 20),
        keys.OBSERVATION: (4, 63),
        keys.REWARD: (4, 1),
    }
    for key, shape in shapes.items():
        value = td["next", key]
        assert value.shape == shape and value.dtype == torch.float32, key
    for key in (keys.SUCCESS, keys.BROKEN, keys.DONE, keys.TERMINATED, keys.TRUNCATED):
        assert td["next", key].shape == (4, 1) and td["next", key].dtype == torch.bool, key
    nxt = td["next"]
    flat = torch.cat([nxt[keys.JOINT_POS], nxt[keys.JOINT_VEL], nxt[keys.TOUCH].flatten(1)], -1)
    torch.testing.assert_close(nxt[keys.OBSERVATION], flat, rtol=0, atol=0)
    torch.testing.assert_close(nxt[keys.TOUCH], nxt[keys.TOUCH_GRID].abs().sum((-2, -1)))
    last_force = torch.as_tensor(env.dm_env.physics.data.actuator_force, dtype=torch.float32)
    torch.testing.assert_close(nxt[keys.ACTUATOR_FORCE][-1], last_force)


def test_same_seed_same_rollout(hand_env):
    envs = [hand_env("touch", seed=seed) for seed in (3, 3, 4)]
    a, b, _ = (env.rollout(30, _policy(1)) for env in envs)
    assert (a == b).all()
    blocks = [env.dm_env.physics.data.mocap_pos[0].tolist() for env in envs]
    assert blocks[0] == blocks[1] != blocks[2]


def test_time_limit_is_truncation(hand_env):
    td = hand_env("explore", seed=0, time_limit=5).rollout(10, _policy(0))
    assert td.shape == (5,)
    assert td["next", keys.TRUNCATED].squeeze(-1).tolist() == [False] * 4 + [True]
    assert not td["next", keys.TERMINATED].any()
    assert td["next", keys.DONE].squeeze(-1).tolist() == [False] * 4 + [True]


def test_success_is_termination_with_flags(hand_env):
    env = hand_env("fragile", seed=0, randomize_block=False)
    action = torch.zeros(20)
    action[3] = 0.25  # flex the index knuckle at a quarter of full speed: a gentle press

    td = env.rollout(80, lambda td: td.set(keys.ACTION, action))
    last = td[-1]["next"]
    assert last[keys.SUCCESS].item() and last[keys.TERMINATED].item()
    assert not last[keys.BROKEN].item() and not last[keys.TRUNCATED].item()
    assert last[keys.REWARD].item() == 5.0
    assert not td["next", keys.SUCCESS][:-1].any()
    assert last[keys.TOUCH][:, 0].max() > 5.0


def test_bad_actions_raise(hand_env):
    env = hand_env("touch", seed=0)
    td = env.reset()
    with pytest.raises(ValueError, match=r"action must have shape \(20,\)"):
        env.step(td.set(keys.ACTION, torch.zeros(3)))
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(td.set(keys.ACTION, torch.full((20,), float("nan"))))


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is not None, reason="OSMesa installed")
def test_render_without_gl_says_what_to_install(hand_env):
    env = hand_env("touch", seed=0)
    env.reset()
    with pytest.raises(RuntimeError, match="apt-get install libosmesa6"):
        env.render()


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is None, reason="needs libosmesa6")
def test_from_pixels(hand_env):
    td = hand_env("touch", seed=0, from_pixels=True).rollout(2, _policy(0))
    assert td["next", keys.PIXELS].shape == (2, 84, 84, 3)
    assert td["next", keys.PIXELS].dtype == torch.uint8
    assert td["next", keys.PIXELS].float().std() > 0


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is None, reason="needs libosmesa6")
def test_gl_context_collected_in_a_reference_cycle_does_not_hang():
    # With dm_control's render thread, the cyclic garbage collector stops that thread before it
    # runs the context's __del__, which then waits forever for it (the suite hung here).
    from dm_control._render import executor

    assert executor.RenderExecutor is executor.PassthroughRenderExecutor
    env = make_env("touch", seed=0, from_pixels=True)
    env.rollout(2)
    physics, env.cycle = env.dm_env.physics, env
    del env
    assert gc.collect() > 0
    assert physics._contexts is None  # freed by the env's close()


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is not None, reason="OSMesa installed")
def test_osmesa_requested_but_missing_is_a_clear_error(tmp_path):
    """MUJOCO_GL=osmesa without libOSMesa: import and stepping work, render() says what to do."""
    code = (
        "import gentlerl.envs as e\n"
        "env = e.make_env('touch', seed=0); env.rand_step(env.reset())\n"
        "try:\n    env.render()\nexcept RuntimeError as err:\n    print('ERR', err)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**os.environ, "MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert "ERR no OpenGL backend to render with" in out.stdout
    assert "libosmesa6" in out.stdout


def test_steps_carry_the_cpu_device_and_collectors_cast_nothing(hand_env):
    """Device-less tensordicts made TorchRL's collector copy every step ``.to("cpu")``: the env's
    outputs name their device, and training's collector runs env, policy and batch on one."""
    from functools import partial

    from gentlerl.config import CollectorConfig
    from gentlerl.models import make_actor, make_exploration_policy
    from gentlerl.training.builders import make_collector

    env = hand_env("touch", seed=0)
    td = env.reset()
    assert td.device == torch.device("cpu")
    assert env.rand_step(td)["next"].device == torch.device("cpu")
    policy = make_exploration_policy(make_actor(63, 20, (8,)), 0.3, action_dim=20)
    collector = make_collector(
        CollectorConfig(frames_per_batch=8, num_envs=2, env_threads=1),
        partial(make_env, "explore", time_limit=50), policy, 16, 0, seed=0,
    )  # fmt: skip
    try:
        devices = {collector.env_device, collector.policy_device, collector.storing_device}
        assert devices == {torch.device("cpu")}
        batch = next(iter(collector))
        assert batch.batch_size == (2, 4) and batch.device == torch.device("cpu")
    finally:
        collector.shutdown()


def test_the_hand_env_refuses_pickle_in_one_line():
    """The finding: unpickling the hand env (or a SumRewards appended to it) aborted the process
    with a double free; it is now a TypeError before anything is written."""
    import pickle

    from torchrl.envs import TransformedEnv

    from gentlerl.rewards import SumRewards

    for env in (make_env("touch", seed=0), make_env("touch", seed=0, num_envs=2)):
        with pytest.raises(TypeError, match=r"cannot be pickled \(its MuJoCo model would be freed"):
            pickle.dumps(env)
    with pytest.raises(TypeError, match="HandEnv cannot be pickled"):
        pickle.dumps(TransformedEnv(make_env("touch", seed=0), SumRewards(["reward"])))
