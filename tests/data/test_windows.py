"""Windows of raw steps behind n-step transitions, and recomputing penalty surprise from them."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.data import WINDOW, NStepWriter, make_replay_buffer, nstep_return, nstep_windows
from gentlerl.rewards import IntrinsicRewards


def _trajectory(T=12, terminal_at=6, obs_dim=1, act_dim=1):
    """obs t = t; penalty -t (none at t = 0); the episode terminates at `terminal_at`."""
    term = torch.zeros(T, 1, dtype=torch.bool)
    term[terminal_at] = True
    t = torch.arange(T).float().unsqueeze(-1)
    return TensorDict(
        {
            "observation": t.expand(T, obs_dim).clone(),
            "action": torch.linspace(-1, 1, T).unsqueeze(-1).expand(T, act_dim).clone(),
            "next": {
                "observation": (t + 1).expand(T, obs_dim).clone(),
                "reward": torch.zeros(T, 1),
                "penalty": -t,
                "done": term.clone(),
                "terminated": term.clone(),
                "truncated": torch.zeros(T, 1, dtype=torch.bool),
            },
        },
        [T],
    )


def test_nstep_windows_unfold_time():
    steps = TensorDict({"x": torch.arange(6).float()}, [6])
    win = nstep_windows(steps, 3, 4)
    assert win.batch_size == torch.Size([4, 3])
    assert win["x"].tolist() == [[0, 1, 2], [1, 2, 3], [2, 3, 4], [3, 4, 5]]
    with pytest.raises(ValueError, match="count"):
        nstep_windows(steps, 3, 5)  # only 4 full windows in 6 steps


def test_nstep_return_stops_at_k():
    rewards = torch.tensor([[1.0, 2.0, 4.0], [1.0, 2.0, 4.0]]).unsqueeze(-1)
    # k = 3: 1 + .5*2 + .25*4 = 3; k = 2: 1 + .5*2 = 2
    assert nstep_return(rewards, torch.tensor([3, 2]), 0.5).squeeze(-1).tolist() == [3.0, 2.0]


def test_writer_windows_reproduce_the_stored_nstep_sums_across_writes():
    """Summed over its window, the raw penalty gives back what MultiStepTransform stored, also
    for transitions whose window crosses two writes or ends at the terminal step."""
    rb = make_replay_buffer(100, 4, prioritized=False, n_steps=None)
    writer = NStepWriter(
        rb, 3, 0.9, ["reward", "penalty"], window_keys=["observation", ("next", "penalty")]
    )
    data = _trajectory()
    writer.extend(data[:7])
    writer.extend(data[7:])
    stored = rb[:]
    assert len(rb) == 12 - 3
    assert stored[WINDOW, "observation"][:, :, 0].tolist()[5] == [5.0, 6.0, 7.0]
    assert stored["steps_to_next_obs"].tolist() == [3, 3, 3, 3, 3, 2, 1, 3, 3]
    again = nstep_return(stored[WINDOW, "next", "penalty"], stored["steps_to_next_obs"], 0.9)
    torch.testing.assert_close(again, stored["next", "penalty"])
    # -(0 + .9 * 1 + .81 * 2) = -2.52 at t = 0; -(5 + .9 * 6) = -10.4 at t = 5 (terminal at 6)
    assert again[0].item() == pytest.approx(-2.52) and again[5].item() == pytest.approx(-10.4)


def test_rescore_windows_scores_penalty_surprise_with_the_current_target_model():
    obs_dim, act_dim = 4, 2
    rewards = IntrinsicRewards(
        "r+rf+rsp",
        GentlenessConfig(reward_delay=0, model_hidden=16, ensemble_size=3),
        obs_dim=obs_dim,
        action_dim=act_dim,
        feature_shapes={},
    )
    rewards.step(0)
    (rsp,) = rewards.rescored
    assert rewards.window_keys == ["observation", "action", ("next", keys.PENALTY)]
    data = _trajectory(obs_dim=obs_dim, act_dim=act_dim)
    data = rsp(data)  # r^sp per step under the model as it is now
    rb = make_replay_buffer(100, 4, prioritized=False, n_steps=None)
    writer = NStepWriter(
        rb, 3, 0.9, ["reward", keys.PENALTY, keys.PENALTY_SURPRISE], rewards.window_keys
    )
    writer.extend(data)
    batch = rb[:]
    stored = batch["next", keys.PENALTY_SURPRISE].clone()
    metrics = rewards.rescore_windows(batch, 0.9)
    torch.testing.assert_close(batch["next", keys.PENALTY_SURPRISE], stored)  # same model
    assert metrics["penalty_surprise_per_contact_step"] > 0
    # A new target model (another copy of the trained model): the stored bonus is replaced.
    with torch.no_grad():
        rewards.losses["penalty"].target_model_params.apply_(lambda p: p.add_(0.5))
    rewards.rescore_windows(batch, 0.9)
    changed = batch["next", keys.PENALTY_SURPRISE]
    assert not torch.allclose(changed, stored)
    per_step = rsp(_trajectory(obs_dim=obs_dim, act_dim=act_dim))["next", keys.PENALTY_SURPRISE]
    # t = 0: 0 (no penalty at step 0) + .9 r_1 + .81 r_2, all under the new model
    expected = 0.9 * per_step[1] + 0.81 * per_step[2]
    torch.testing.assert_close(changed[0], expected)


def test_rescore_windows_names_the_missing_window():
    rewards = IntrinsicRewards(
        "r+rf+rsp", GentlenessConfig(model_hidden=8), obs_dim=1, action_dim=1, feature_shapes={}
    )
    with pytest.raises(KeyError, match="window"):
        rewards.rescore_windows(_trajectory(), 0.9)


def test_paper_scale_stores_the_surprise():
    rewards = IntrinsicRewards(
        "r+rf+rsp",
        GentlenessConfig(model_hidden=8, rescore_surprise=False),
        obs_dim=1,
        action_dim=1,
        feature_shapes={},
    )
    assert rewards.rescored == [] and rewards.window_keys == []
    batch = _trajectory()
    assert rewards.rescore_windows(batch, 0.9) == {}


def test_writes_shorter_than_n_steps_lose_nothing_across_a_resume():
    """Four envs, writes of 2 steps (n = 3): the tail keeps the steps held from earlier writes,
    so a resume in the middle stores as many transitions as a straight run, windows included."""
    data = torch.stack([_trajectory(T=16, terminal_at=15) for _ in range(4)])  # [4, 16]

    def run(resume_at=None):
        rb = make_replay_buffer(200, 4, prioritized=False, n_steps=None)
        writer = NStepWriter(
            rb, 3, 0.9, ["reward", "penalty"], ["observation", ("next", "penalty")]
        )
        for i in range(8):
            if i == resume_at:
                state = writer.state_dict()
                writer = NStepWriter(rb, 3, 0.9, ["reward", "penalty"], writer.window_keys)
                writer.load_state_dict(state)
            writer.extend(data[:, 2 * i : 2 * i + 2])
        return rb[:]

    straight, resumed = run(), run(resume_at=4)
    assert len(straight) == 4 * (16 - 3)
    assert len(resumed) == len(straight)
    again = nstep_return(resumed[WINDOW, "next", "penalty"], resumed["steps_to_next_obs"], 0.9)
    torch.testing.assert_close(again, resumed["next", "penalty"])


def test_writer_windows_keep_each_env_row_of_a_named_collector_batch_apart():
    """A collector's ``[B, T]`` batch names its time dim; each row's windows hold that row's steps
    and sum back to its stored n-step penalty."""
    rb = make_replay_buffer(100, 4, prioritized=False, n_steps=None)
    writer = NStepWriter(
        rb, 3, 0.9, ["reward", "penalty"], window_keys=["observation", ("next", "penalty")]
    )
    rows = torch.stack([_trajectory(terminal_at=11), _trajectory(terminal_at=11)])
    rows["observation"][1] += 100.0  # row 1's observations are 100 .. 111
    rows = rows.to("cpu")  # a collector batch has a device, and names its time dim
    rows.names = [None, "time"]
    writer.extend(rows)
    stored = rb[:]
    assert len(rb) == 2 * (12 - 3)
    firsts = stored[WINDOW, "observation"][:, 0, 0]
    assert sorted(firsts.tolist()) == [*range(9), *range(100, 109)]
    for window in stored[WINDOW, "observation"][..., 0].tolist():
        assert window == [window[0], window[0] + 1, window[0] + 2]  # never across rows
    again = nstep_return(stored[WINDOW, "next", "penalty"], stored["steps_to_next_obs"], 0.9)
    torch.testing.assert_close(again, stored["next", "penalty"])
