"""The checklist every gentleness transform passes, after TorchRL's
``test/transforms/_transforms_common.py``: appended to one env, to a ``SerialEnv`` (outside and
inside its envs) and to a ``ParallelEnv`` (outside and inside its workers), on a batch with no env,
inside a ``Compose``, as a replay-buffer transform, and through ``clone`` / ``state_dict``.

Each transform's reference is its output on the toy env's pressing rollout scored as one batch;
every case must give those rewards, which are informative (non-zero once the fingertip presses,
steps 6 on). The model-reading transforms (``ModelRewardTransform``) refuse to run inside a
``ParallelEnv``'s workers, by design: a worker would hold a copy of the model that the loss's
updates never reach. ``RescoreRewards`` is a replay-buffer transform only (no env cases).
"""

import functools
import multiprocessing
from collections.abc import Callable
from dataclasses import dataclass

import pytest
import torch
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import Compose, EnvBase, ParallelEnv, SerialEnv, Transform, TransformedEnv
from torchrl.envs.utils import check_env_specs

import gentlerl.transforms
from gentlerl import keys
from gentlerl.rewards import RescoreRewards, SumRewards
from gentlerl.transforms import (
    DynamicsSurprise,
    ExcessPenalty,
    ForcePenalty,
    ICMReward,
    ImpactPenalty,
    ModelRewardTransform,
    PenaltySurprise,
    TorquePenalty,
    TransitionTransform,
)
from tests.helpers import make_reward_transforms, pressing_rollout
from tests.toy_env import ToyHandEnv


def _penalty_env() -> EnvBase:
    """The toy env with ``penalty`` written: what PenaltySurprise and SumRewards read."""
    return TransformedEnv(ToyHandEnv(), ImpactPenalty())


def _stack(variant: str, seed: int, gate: bool):
    stack = make_reward_transforms(variant, seed=seed, reward_delay=1, hidden=16, ensemble_size=2)
    if gate:
        stack.step(1)  # the reward delay reached: the models' rewards count
    return stack


def _model_transform(variant: str, cls: type, seed: int, gate: bool) -> ModelRewardTransform:
    (transform,) = [t for t in _stack(variant, seed, gate).transform if isinstance(t, cls)]
    return transform


def _rescore(seed: int, gate: bool) -> RescoreRewards:
    stack = _stack("r+rf+rsp", seed, gate)
    return stack.rescore_transform(SumRewards(stack.reward_keys))


@dataclass(frozen=True)
class Subject:
    make: Callable[[int, bool], Transform]  # (seed, gate open) -> transform; a seed, one model
    key: str  # the reward it writes under "next"
    base: Callable[[], EnvBase] = ToyHandEnv  # the env it is appended to
    env: bool = True  # appended to envs; False: a replay-buffer transform only

    def model_transforms(self, transform: Transform) -> list[ModelRewardTransform]:
        if isinstance(transform, RescoreRewards):
            return list(transform.rewards)
        return [transform] if isinstance(transform, ModelRewardTransform) else []


SUBJECTS = {
    "ImpactPenalty": Subject(lambda seed, gate: ImpactPenalty(), keys.PENALTY),
    "ForcePenalty": Subject(lambda seed, gate: ForcePenalty(), keys.FORCE_PENALTY),
    "ExcessPenalty": Subject(  # reads the impact ImpactPenalty writes; the press exceeds 0.01 N
        lambda seed, gate: ExcessPenalty(0.01), keys.EXCESS_PENALTY, _penalty_env
    ),
    "TorquePenalty": Subject(lambda seed, gate: TorquePenalty(), keys.TORQUE_PENALTY),
    "DynamicsSurprise": Subject(
        functools.partial(_model_transform, "r+rf+rs", DynamicsSurprise), keys.DYNAMICS_SURPRISE
    ),
    "PenaltySurprise": Subject(
        functools.partial(_model_transform, "r+rf+rsp", PenaltySurprise),
        keys.PENALTY_SURPRISE,
        _penalty_env,
    ),
    "ICMReward": Subject(functools.partial(_model_transform, "r+icm", ICMReward), keys.ICM_REWARD),
    "SumRewards": Subject(
        lambda seed, gate: SumRewards([keys.REWARD, keys.PENALTY]), keys.REWARD, _penalty_env
    ),
    "RescoreRewards": Subject(_rescore, keys.REWARD, _penalty_env, env=False),
}
ENV_SUBJECTS = [name for name, subject in SUBJECTS.items() if subject.env]
MODEL_SUBJECTS = ["DynamicsSurprise", "PenaltySurprise", "ICMReward", "RescoreRewards"]


def _is_model(name: str) -> bool:
    return name in MODEL_SUBJECTS


def _reference(subject: Subject):
    """(transform, the raw pressing rollout, the transform's rewards on it scored as a batch)."""
    transform = subject.make(0, True)
    raw = pressing_rollout(subject.base())
    reference = transform(raw.clone())["next", subject.key]
    assert reference.shape == (12, 1) and (reference[6:] != 0).all()  # informative
    return transform, raw, reference


def _rows_equal(rollout, key, reference) -> None:
    assert rollout["next", key].shape == (2, 12, 1)
    for row in rollout["next", key]:
        torch.testing.assert_close(row, reference)


def _in_env(base: Callable[[], EnvBase], transform: Transform) -> TransformedEnv:
    """``base()`` with ``transform`` appended (a copy of its own each call: a transform belongs to
    one env)."""
    env = base()
    env = env if isinstance(env, TransformedEnv) else TransformedEnv(env)
    env.append_transform(transform.clone())
    return env


def test_every_gentleness_transform_is_on_the_checklist():
    exported = {
        name
        for name in gentlerl.transforms.__all__
        if isinstance(cls := getattr(gentlerl.transforms, name), type)
        and issubclass(cls, TransitionTransform)
        and cls not in (TransitionTransform, ModelRewardTransform)
        and name == cls.__name__  # not an alias (ICM)
    }
    assert exported <= set(SUBJECTS), f"not on the checklist: {exported - set(SUBJECTS)}"
    assert {"SumRewards", "RescoreRewards"} <= set(SUBJECTS)  # the drop-in's own transforms
    for name in MODEL_SUBJECTS:
        subject = SUBJECTS[name]
        assert subject.model_transforms(subject.make(0, True)), name


@pytest.mark.parametrize("name", ENV_SUBJECTS)
def test_env(name):
    subject = SUBJECTS[name]
    transform, _, reference = _reference(subject)
    env = _in_env(subject.base, transform)
    check_env_specs(env)
    assert subject.key in env.reward_keys
    torch.testing.assert_close(pressing_rollout(env)["next", subject.key], reference)


def _agrees(env, key, reference) -> None:
    """``env`` passes ``check_env_specs`` and its pressing rollout writes ``reference``'s ``key``
    rows; the env is closed either way."""
    try:
        check_env_specs(env)
        _rows_equal(pressing_rollout(env), key, reference)
    finally:
        env.close()


@pytest.mark.parametrize("name", ENV_SUBJECTS)
def test_serial_env(name):
    """Appended to a SerialEnv (outside its envs)."""
    subject = SUBJECTS[name]
    transform, _, reference = _reference(subject)
    env = TransformedEnv(SerialEnv(2, subject.base), transform.clone())
    _agrees(env, subject.key, reference)


@pytest.mark.parametrize("name", ENV_SUBJECTS)
def test_env_in_serial(name):
    """Inside each env of a SerialEnv: the same process, so the model-reading ones run too."""
    subject = SUBJECTS[name]
    transform, _, reference = _reference(subject)
    env = SerialEnv(2, functools.partial(_in_env, subject.base, transform))
    _agrees(env, subject.key, reference)


@pytest.mark.parametrize("name", ENV_SUBJECTS)
def test_parallel_env(name):
    """Appended to a ParallelEnv, outside its workers: how the model-reading ones are used."""
    subject = SUBJECTS[name]
    transform, _, reference = _reference(subject)
    env = TransformedEnv(ParallelEnv(2, subject.base, mp_start_method="fork"), transform.clone())
    _agrees(env, subject.key, reference)


@pytest.mark.parametrize("name", ENV_SUBJECTS)
def test_env_in_parallel(name, capfd):
    """Inside a ParallelEnv's workers: the model-free ones run; a model-reading one refuses (its
    worker dies naming the process its model trains in), by design."""
    subject = SUBJECTS[name]
    transform, _, reference = _reference(subject)
    make = functools.partial(_in_env, subject.base, transform)
    env = ParallelEnv(2, make, mp_start_method="fork")
    if not _is_model(name):
        try:
            _rows_equal(pressing_rollout(env), subject.key, reference)
        finally:
            env.close()
        return
    try:
        with pytest.raises(RuntimeError, match="worker .* dead"):
            pressing_rollout(env)
    finally:
        with pytest.raises(RuntimeError, match="process failed"):
            env.close()  # it reports the worker that died
    err = capfd.readouterr().err
    assert f"RuntimeError: {name} runs in process" in err and "its model trains in process" in err
    for child in multiprocessing.active_children():  # no worker left behind
        child.join(timeout=10)
    assert not [c for c in multiprocessing.active_children() if c.is_alive()]


@pytest.mark.parametrize("name", SUBJECTS)
def test_no_env(name):
    """On a batch: one transition at a time, the whole rollout and a [2, 12] batch agree."""
    subject = SUBJECTS[name]
    transform, raw, reference = _reference(subject)
    singles = [transform(raw[i : i + 1].clone())["next", subject.key] for i in range(12)]
    torch.testing.assert_close(torch.cat(singles), reference)
    stacked = transform(torch.stack([raw, raw]).clone())["next", subject.key]
    _rows_equal({("next", subject.key): stacked}, subject.key, reference)


@pytest.mark.parametrize("name", SUBJECTS)
def test_compose(name):
    subject = SUBJECTS[name]
    transform, raw, reference = _reference(subject)
    composed = Compose(transform.clone())
    torch.testing.assert_close(composed(raw.clone())["next", subject.key], reference)
    if subject.env:
        env = _in_env(subject.base, Compose(transform.clone()))
        check_env_specs(env)
        torch.testing.assert_close(pressing_rollout(env)["next", subject.key], reference)


@pytest.mark.parametrize("name", SUBJECTS)
def test_replay_buffer(name):
    """A replay-buffer transform scores each sample; the storage keeps the raw transitions."""
    subject = SUBJECTS[name]
    transform, raw, reference = _reference(subject)
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(20), batch_size=5)
    rb.append_transform(transform.clone())
    rb.extend(raw.clone())
    torch.testing.assert_close(rb[:]["next", subject.key], reference)
    sample = rb.sample()
    torch.testing.assert_close(sample["next", subject.key], reference[sample["index"]])
    stored = rb.storage[:]
    if subject.key != keys.REWARD:
        assert ("next", subject.key) not in stored.keys(True)
    torch.testing.assert_close(stored["next", keys.REWARD], raw["next", keys.REWARD])


@pytest.mark.parametrize("name", SUBJECTS)
def test_clone_and_state_dict(name):
    """``clone`` gives the same rewards and, for a model-reading transform, shares its model; a
    ``state_dict`` loaded into a fresh transform of the same seed gives the same rewards (a
    model-reading one's gate is in it, closed before the load)."""
    subject = SUBJECTS[name]
    transform, raw, reference = _reference(subject)
    clone = transform.clone()
    torch.testing.assert_close(clone(raw.clone())["next", subject.key], reference)

    fresh = subject.make(0, False)
    state = transform.state_dict()
    models = subject.model_transforms(fresh)
    if isinstance(transform, RescoreRewards):
        # Its transforms belong to the env's chain, which checkpoints them (gate included).
        assert not state
        for mine, theirs in zip(models, subject.model_transforms(transform), strict=True):
            mine.load_state_dict(theirs.state_dict())
    elif models:
        assert list(state) == ["active"] and bool(state["active"])  # the model is the loss's
        closed = fresh(raw.clone())["next", subject.key]
        assert (closed == 0).all()
    fresh.load_state_dict(state)
    torch.testing.assert_close(fresh(raw.clone())["next", subject.key], reference)

    for model in subject.model_transforms(transform):  # an update of the loss's model ...
        with torch.no_grad():
            for tensor in model.params.values(True, True):
                tensor.add_(0.05)
    if models:
        updated = transform(raw.clone())["next", subject.key]
        assert not torch.allclose(updated, reference)
        # ... reaches the clone: shared, not copied
        torch.testing.assert_close(clone(raw.clone())["next", subject.key], updated)
