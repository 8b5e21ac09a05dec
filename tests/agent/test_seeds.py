"""SeedBatchedLearner: S seeds in one vmapped step equal S separate Learners."""

import pytest
import torch
from tensordict import TensorDict

from gentlerl.agent.learner import Learner
from gentlerl.agent.seeds import SeedBatchedLearner
from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss

KEYS = ["reward", "penalty"]


def _loss(seed):
    torch.manual_seed(seed)
    critic = make_critic(3, 1, 2, (16, 8), 11, v_min=-5.0, v_max=[5.0, 0.0])
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=KEYS)
    loss.make_value_estimator(gamma=0.9)
    return loss


def _batch(n, seed):
    g = torch.Generator().manual_seed(seed)
    nxt = {
        "observation": torch.randn(n, 3, generator=g),
        "reward": torch.rand(n, 1, generator=g),
        "penalty": -torch.rand(n, 1, generator=g),
        "terminated": torch.rand(n, 1, generator=g) < 0.2,
    }
    obs, act = torch.randn(n, 3, generator=g), torch.rand(n, 1, generator=g) * 2 - 1
    return TensorDict({"observation": obs, "action": act, "next": nxt}, [n])


OPTIONS = dict(lr_actor=1e-3, lr_critic=1e-2, target_update_period=2)


def test_seed_batched_updates_equal_separate_learners():
    seeds = [0, 1, 2]
    singles = [Learner(_loss(s), **OPTIONS) for s in seeds]
    batched = SeedBatchedLearner([_loss(s) for s in seeds], **OPTIONS)
    for step in range(5):  # two target copies (after updates 2 and 4)
        rows = [_batch(32, 10 * step + s) for s in seeds]
        stacked = torch.stack([r.clone() for r in rows])
        out = batched.update(stacked)
        for s, learner in enumerate(singles):
            ref = learner.update(rows[s])
            for key in ("loss_value", "loss_actor", "value_reward", "value_penalty"):
                torch.testing.assert_close(out[key][s], ref[key], rtol=1e-5, atol=1e-6)
            torch.testing.assert_close(stacked["td_error"][s], rows[s]["td_error"])
    for s, learner in enumerate(singles):
        got = batched.write_back(s).network_params()
        want = learner.loss.network_params()
        for key, value in want.items(True, True):
            torch.testing.assert_close(got[key], value, rtol=1e-5, atol=1e-6)


def test_seeds_stay_independent():
    """A seed's parameters do not move when only another seed's batch changes."""
    a = SeedBatchedLearner([_loss(0), _loss(1)], **OPTIONS)
    b = SeedBatchedLearner([_loss(0), _loss(1)], **OPTIONS)
    batch = torch.stack([_batch(16, 0), _batch(16, 1)])
    other = batch.clone()
    other[1] = _batch(16, 99)
    for _ in range(3):
        a.update(batch.clone())
        b.update(other.clone())
    moved = []
    for key, value in a.params["value"].items(True, True):
        torch.testing.assert_close(value[0], b.params["value"][key][0], rtol=0, atol=0)
        moved.append(not torch.equal(value[1], b.params["value"][key][1]))
    assert all(moved)


def test_refuses_a_batch_without_the_seed_dimension():
    learner = SeedBatchedLearner([_loss(0), _loss(1)], **OPTIONS)
    with pytest.raises(ValueError, match=r"shaped \[num_seeds=2, B\], got \(16,\)"):
        learner.update(_batch(16, 0))


def test_cudagraphs_refused_on_cpu():
    with pytest.raises(ValueError, match="needs a CUDA learner, this one is on cpu"):
        SeedBatchedLearner([_loss(0)], cudagraphs=True, **OPTIONS)


def test_shared_seeds_act_with_the_batched_weights_and_their_optimisers_get_their_rows():
    """share=True: each seed's own actor acts with its row of the stack after batched updates
    (the separate learners' actions, no write_back); optimizer_rows hands each seed's own
    Adam its row, so that a seed's learner then steps as the separate learner does."""
    seeds = [0, 1]
    singles = [Learner(_loss(s), **OPTIONS) for s in seeds]
    own = [Learner(_loss(s), **OPTIONS) for s in seeds]  # the seeds' own learners, shared
    batched = SeedBatchedLearner([learner.loss for learner in own], share=True, **OPTIONS)
    obs = TensorDict({"observation": torch.randn(4, 3)}, [4])
    for step in range(3):
        rows = [_batch(16, 10 * step + s) for s in seeds]
        batched.update(torch.stack([r.clone() for r in rows]))
        for learner, row in zip(singles, rows, strict=True):
            learner.update(row)
    for mine, ref in zip(own, singles, strict=True):
        act = mine.policy(obs.clone())["action"]
        torch.testing.assert_close(act, ref.policy(obs.clone())["action"], rtol=1e-5, atol=1e-6)
    batched.optimizer_rows([learner.optimizer for learner in own])
    # Adam's moments with step 3, then step 4 on each seed alone: the separate learners' step 4
    for s, (mine, ref) in enumerate(zip(own, singles, strict=True)):
        mine.target_updater.counter = ref.target_updater.counter
        row = _batch(16, 50 + s)
        mine.update(row.clone())
        ref.update(row)
        for key, value in ref.loss.network_params().items(True, True):
            got = mine.loss.network_params()[key]
            torch.testing.assert_close(got, value, rtol=1e-5, atol=1e-6)
