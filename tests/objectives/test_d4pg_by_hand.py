"""One MultiHeadD4PGLoss update worked out by hand: the golden losses cannot bless a bug here.

``tests/data/golden_losses.json`` is written by the code it checks (it once held a bug in the
target statistics as its expected values). This test computes one value loss and one actor loss
of a tiny batch (2 samples, 2 heads with different supports, 1 hidden layer, 5 atoms) from the
loss's own parameter tensors with everything else written out here:

- the networks' forward passes (Linear -> LayerNorm -> tanh -> Linear, the paper's trunk);
- the target statistics: the *target* actor's action at s', the *target* critic head's
  distribution there, the n-step discount gamma^n, and the bootstrap cut by ``terminated``
  for the episodic head only;
- the categorical projection as C51's algorithm states it (Bellemare et al. 2017, Alg. 1;
  Barth-Maron et al. 2018, eq. 7): each moved atom's mass split between its floor and ceiling
  atoms, in plain Python;
- the cross-entropy, the priority-weighted batch mean, the per-sample priority, and the actor's
  weighted sum of the heads' expected values at (s, pi(s)) under the *online* critic.

The target parameters are moved away from the online ones, so reading the wrong set shows.
"""

import math

import pytest
import torch
from tensordict import TensorDict

from gentlerl.models import make_actor, make_critic
from gentlerl.objectives import MultiHeadD4PGLoss

GAMMA = 0.9
ATOMS = 5
#: head 0 (task, episodic) on [-2, 6], head 1 (penalty, non-episodic) on [-4, 0]
V_MIN, V_MAX = (-2.0, -4.0), (6.0, 0.0)
#: the penalty head's weight in the actor's objective
HEAD_WEIGHTS = (1.0, 1.5)


def _loss():
    torch.manual_seed(3)
    actor = make_actor(2, 1, hidden=(3,))
    critic = make_critic(2, 1, 2, (4,), ATOMS, v_min=list(V_MIN), v_max=list(V_MAX))
    loss = MultiHeadD4PGLoss(
        actor, critic, reward_keys=["reward", "penalty"], non_episodic_keys=["penalty"]
    )
    loss.make_value_estimator(gamma=GAMMA)
    loss.set_head_weight("penalty", HEAD_WEIGHTS[1])
    gen = torch.Generator().manual_seed(7)
    with torch.no_grad():  # targets that are not copies of the online networks
        for params in (loss.target_actor_network_params, loss.target_value_network_params):
            for p in params.values(True, True):
                p.add_(0.5 * torch.randn(p.shape, generator=gen))
    return loss


def _batch():
    # sample 0: n = 3 steps, not terminated; sample 1: n = 1, terminated, a task reward of 7
    # beyond the task head's top atom (clipped to 6).
    return TensorDict(
        {
            "observation": torch.tensor([[0.5, -1.0], [1.5, 0.25]]),
            "action": torch.tensor([[0.3], [-0.8]]),
            "steps_to_next_obs": torch.tensor([3, 1]),
            "priority_weight": torch.tensor([0.25, 1.0]),
            "next": {
                "observation": torch.tensor([[0.0, 2.0], [-1.0, 0.5]]),
                "reward": torch.tensor([[0.5], [7.0]]),
                "penalty": torch.tensor([[-1.0], [-0.5]]),
                "terminated": torch.tensor([[False], [True]]),
            },
        },
        [2],
    )


def _d(params, *key) -> torch.Tensor:
    return params.get(("module", *key)).detach().double()


def _layer_norm(h: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    mean = h.mean()
    var = ((h - mean) ** 2).mean()  # biased, as LayerNorm
    return (h - mean) / torch.sqrt(var + 1e-5) * weight + bias


def _actor(params, s: list[float]) -> float:
    """a = tanh(W1 tanh(LN(W0 s + b0)) + b1)."""
    h = _d(params, "0", "weight") @ torch.tensor(s, dtype=torch.float64) + _d(params, "0", "bias")
    h = torch.tanh(_layer_norm(h, _d(params, "1", "weight"), _d(params, "1", "bias")))
    return torch.tanh(_d(params, "3", "weight") @ h + _d(params, "3", "bias")).item()


def _critic_logits(params, k: int, s: list[float], a: float) -> list[float]:
    """Head k: logits = Wh tanh(LN(x W0 + b0)) + bh, x = [s, a]."""
    x = torch.tensor([*s, a], dtype=torch.float64)
    h = x @ _d(params, "layers", "0", "weight")[k] + _d(params, "layers", "0", "bias")[k, 0]
    norm_w, norm_b = _d(params, "norm", "weight")[k, 0], _d(params, "norm", "bias")[k, 0]
    h = torch.tanh(_layer_norm(h, norm_w, norm_b))
    return (h @ _d(params, "head", "weight")[k] + _d(params, "head", "bias")[k, 0]).tolist()


def _softmax(logits: list[float]) -> list[float]:
    top = max(logits)
    e = [math.exp(v - top) for v in logits]
    return [v / sum(e) for v in e]


def _atoms(k: int) -> list[float]:
    dz = (V_MAX[k] - V_MIN[k]) / (ATOMS - 1)
    return [V_MIN[k] + j * dz for j in range(ATOMS)]


def _c51_projection(probs, reward, discount, k) -> list[float]:
    """Bellemare et al. 2017, Alg. 1: Tz_j = clip(r + d z_j), b_j = (Tz_j - V_min) / dz,
    m_l += p_j (u - b_j), m_u += p_j (b_j - l); all of p_j to l when b_j is an atom."""
    z, dz = _atoms(k), (V_MAX[k] - V_MIN[k]) / (ATOMS - 1)
    m = [0.0] * ATOMS
    for zj, pj in zip(z, probs, strict=True):
        tz = min(V_MAX[k], max(V_MIN[k], reward + discount * zj))
        b = (tz - V_MIN[k]) / dz
        low, up = math.floor(b), math.ceil(b)
        if low == up:
            m[low] += pj
        else:
            m[low] += pj * (up - b)
            m[up] += pj * (b - low)
    return m


def _by_hand(loss, batch):
    """(loss_value, per-head losses, priorities, loss_actor, per-head mean values)."""
    online_a, online_v = loss.actor_network_params, loss.value_network_params
    target_a, target_v = loss.target_actor_network_params, loss.target_value_network_params
    weights = batch["priority_weight"].tolist()
    ce = [[0.0, 0.0], [0.0, 0.0]]  # [sample][head]
    objective, q = [0.0, 0.0], [[0.0, 0.0], [0.0, 0.0]]
    for i in range(2):
        s, a = batch["observation"][i].tolist(), batch["action"][i].item()
        s_next = batch["next", "observation"][i].tolist()
        n = int(batch["steps_to_next_obs"][i])
        terminated = bool(batch["next", "terminated"][i])
        a_next = _actor(target_a, s_next)  # the target actor at s'
        pi = _actor(online_a, s)  # the online actor at s, for the actor loss
        for k, key in enumerate(("reward", "penalty")):
            episodic = k == 0
            discount = 0.0 if (terminated and episodic) else GAMMA**n
            next_probs = _softmax(_critic_logits(target_v, k, s_next, a_next))
            target = _c51_projection(next_probs, batch["next", key][i].item(), discount, k)
            assert sum(target) == pytest.approx(1.0)
            logits = _critic_logits(online_v, k, s, a)
            top = max(logits)
            log_z = top + math.log(sum(math.exp(v - top) for v in logits))
            ce[i][k] = -sum(t * (v - log_z) for t, v in zip(target, logits, strict=True))
            probs = _softmax(_critic_logits(online_v, k, s, pi))
            q[i][k] = sum(p * z for p, z in zip(probs, _atoms(k), strict=True))
            objective[i] += HEAD_WEIGHTS[k] * q[i][k]
    wsum = sum(weights)
    per_head = [sum(weights[i] * ce[i][k] for i in range(2)) / wsum for k in range(2)]
    priority = [(ce[i][0] + ce[i][1]) / 2 for i in range(2)]
    actor = -sum(weights[i] * objective[i] for i in range(2)) / wsum
    values = [(q[0][k] + q[1][k]) / 2 for k in range(2)]
    return sum(per_head), per_head, priority, actor, values


def test_one_update_of_the_value_and_actor_losses_by_hand():
    loss, batch = _loss(), _batch()
    value, per_head, priority, actor, values = _by_hand(loss, batch)
    got_value, info = loss.loss_value(batch)
    assert got_value.item() == pytest.approx(value, rel=1e-5)
    assert info["per_head"].tolist() == pytest.approx(per_head, rel=1e-5)
    assert batch["td_error"].tolist() == pytest.approx(priority, rel=1e-5)
    got_actor, info = loss.loss_actor(batch)
    assert got_actor.item() == pytest.approx(actor, rel=1e-5)
    assert info["value"].tolist() == pytest.approx(values, rel=1e-5)
    out = loss(batch.clone())
    assert out["loss_value"].item() == pytest.approx(value, rel=1e-5)
    assert out["loss_actor"].item() == pytest.approx(actor, rel=1e-5)
    assert out["loss_value_penalty"].item() == pytest.approx(per_head[1], rel=1e-5)


def test_the_hand_computed_target_reads_target_networks_and_the_cut():
    # The projected target of each sample and head, compared entry by entry: sample 1's task
    # head is terminal (all mass on the clipped reward 6 = the top atom), its penalty head
    # bootstraps through the termination with gamma^1.
    loss, batch = _loss(), _batch()
    target = loss.target_distribution(batch)
    target_a, target_v = loss.target_actor_network_params, loss.target_value_network_params
    for i, n in ((0, 3), (1, 1)):
        s_next = batch["next", "observation"][i].tolist()
        a_next = _actor(target_a, s_next)
        for k, key in enumerate(("reward", "penalty")):
            discount = 0.0 if (i == 1 and k == 0) else GAMMA**n
            probs = _softmax(_critic_logits(target_v, k, s_next, a_next))
            expected = _c51_projection(probs, batch["next", key][i].item(), discount, k)
            assert target[i, k].tolist() == pytest.approx(expected, abs=1e-6), (i, k)
    assert target[1, 0].tolist() == pytest.approx([0, 0, 0, 0, 1.0], abs=1e-6)
