"""The batched hand env: the same steps as the single env, per-hand resets and seeds, bad input."""

import pytest
import torch
from torchrl._utils import seed_generator
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.envs import BatchedHandEnv, HandEnv
from gentlerl.envs.batched import available_cores

FLEX_INDEX_KNUCKLE = 3  # actuator robot0:A_FFJ2: pressing it succeeds in ~38 steps ("easy")


def _actions(steps: int, n: int, press: list[bool], seed: int = 0) -> torch.Tensor:
    """``[steps, n, 20]`` small random actions; hands in ``press`` also flex the index knuckle."""
    g = torch.Generator().manual_seed(seed)
    actions = (torch.rand(steps, n, 20, generator=g) * 2 - 1) * 0.2
    actions[:, torch.tensor(press), FLEX_INDEX_KNUCKLE] = 1.0
    return actions


def _run(env, actions: torch.Tensor) -> list:
    """``step_and_maybe_reset`` with the given actions; the ``next`` tensordict of every step."""
    td, out = env.reset(), []
    for action in actions:
        td, nxt = env.step_and_maybe_reset(td.set(keys.ACTION, action))
        out.append(td.get("next").clone())
        td = nxt
    return out


def test_one_hand_batched_equals_the_single_env_step_by_step(hand_env):
    """fragile, a 30-step limit and a pressing policy: successes, truncations and resets occur
    (measured: success at step 38 of an episode is past the limit, so both happen here)."""
    kwargs = dict(seed=5, time_limit=30, action_scale=0.05)
    single, batched = hand_env("fragile", **kwargs), hand_env("fragile", num_envs=1, **kwargs)
    assert isinstance(single, HandEnv) and isinstance(batched, BatchedHandEnv)
    actions = _actions(90, 1, [True])
    a = _run(single, actions[:, 0])
    b = _run(batched, actions)
    dones = torch.stack([td[keys.DONE] for td in a]).sum().item()
    assert dones >= 2  # episodes ended (and the envs reset) during the comparison
    assert torch.stack([td[keys.SUCCESS] for td in a]).any()
    for step, (x, y) in enumerate(zip(a, b, strict=True)):
        assert set(x.keys()) == set(y.keys())
        for key in x.keys():
            assert torch.equal(x[key], y[key][0]), (step, key)


def test_hands_reset_on_their_own_and_are_seeded_as_parallel_env_workers(hand_env):
    """Hand 0 presses (its episode ends early and restarts); hand 1 does not: hand 1's trajectory
    is that of a single env seeded with the second seed of TorchRL's seed chain."""
    seed = 7
    batched = hand_env("touch", seed=seed, num_envs=2, num_threads=2, regime="easy")
    actions = _actions(60, 2, [True, False], seed=1)
    b = _run(batched, actions)
    done0 = [td[keys.DONE][0].item() for td in b]
    assert any(done0) and not any(td[keys.DONE][1].item() for td in b)
    single = hand_env("touch", seed=seed_generator(seed), regime="easy")
    a = _run(single, actions[:, 1])
    for x, y in zip(a, b, strict=True):
        assert torch.equal(x[keys.OBSERVATION], y[keys.OBSERVATION][1])
    # After its reset, hand 0 starts from rest again: joint positions 0 at the first step.
    first = done0.index(True)
    assert b[first + 1][keys.JOINT_POS][0].abs().max() < 0.05


def test_threads_do_not_change_the_results(hand_env):
    actions = _actions(20, 3, [True, False, True])
    one, two = (hand_env("touch", seed=0, num_envs=3, num_threads=t) for t in (1, 2))
    for x, y in zip(_run(one, actions), _run(two, actions), strict=True):
        assert (x == y).all()
    assert one.num_threads == 1 and two.num_threads == 2


def test_check_env_specs_and_shapes(hand_env):
    env = hand_env("fragile", seed=0, num_envs=3)
    check_env_specs(env)
    td = env.rollout(4, break_when_any_done=False)
    assert td.batch_size == (3, 4)
    assert td["next", keys.TOUCH_GRID].shape == (3, 4, 5, 3, 4, 4)
    assert td["next", keys.OBSERVATION].shape == (3, 4, 63)
    assert td["next", keys.DONE].dtype == torch.bool


def test_bad_sizes_name_the_field(hand_env):
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1"):
        hand_env("touch", num_envs=0)
    with pytest.raises(ValueError, match="num_threads must be an integer >= 1"):
        hand_env("touch", num_envs=2, num_threads=0)
    with pytest.raises(ValueError, match="num_threads=2 needs num_envs"):
        hand_env("touch", num_threads=2)
    with pytest.warns(UserWarning, match=rf"num_threads={available_cores() + 1} is more than"):
        env = hand_env("touch", num_envs=1, num_threads=available_cores() + 1)
    assert env.num_threads == 1  # never more threads than hands


def test_bad_action_raises_before_any_physics(hand_env):
    env = hand_env("touch", seed=0, num_envs=2)
    td = env.reset()
    qpos = env.dm_envs[0].physics.data.qpos.copy()
    action = torch.zeros(2, 20)
    action[1, 0] = float("nan")
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(td.set(keys.ACTION, action))
    assert (env.dm_envs[0].physics.data.qpos == qpos).all()
