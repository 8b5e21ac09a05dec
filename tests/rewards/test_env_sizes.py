"""What an env's specs tell the agent (``gentlerl.rewards.env_sizes``)."""

import warnings

import pytest
import torch
from torchrl.data import Composite, Unbounded
from torchrl.envs import (
    CatTensors,
    Compose,
    EnvBase,
    ExcludeTransform,
    RenameTransform,
    TransformedEnv,
)

from gentlerl import keys
from gentlerl.config import GentlenessConfig
from gentlerl.rewards import IntrinsicRewards, SumRewards
from gentlerl.rewards.env_sizes import (
    check_env_keys,
    env_feature_shapes,
    env_sizes,
    episode_steps,
    observation_sources,
)
from tests.toy_env import ToyHandEnv


def test_missing_env_keys_are_reported_before_training():
    env = ToyHandEnv()
    rewards = IntrinsicRewards("r+rf", GentlenessConfig(), obs_dim=63, action_dim=20,
                               feature_shapes={})  # fmt: skip
    check_env_keys(
        env, rewards.transform, rewards.reward_keys
    )  # the toy env has the hand env's keys
    no_touch = TransformedEnv(ToyHandEnv(), RenameTransform(["touch"], ["force"]))
    with pytest.raises(ValueError, match="ImpactPenalty reads 'touch', which the env's spec lacks"):
        check_env_keys(no_touch, rewards.transform, rewards.reward_keys)
    no_observation = TransformedEnv(ToyHandEnv(), RenameTransform(["observation"], ["state"]))
    with pytest.raises(ValueError, match=r"key\(s\) \['observation'\] needed by the run"):
        check_env_keys(no_observation, rewards.transform, rewards.reward_keys)
    # success / broken are optional (an external env has neither): judged by its return
    no_outcomes = TransformedEnv(ToyHandEnv(), RenameTransform(["success", "broken"], ["a", "b"]))
    check_env_keys(no_outcomes, rewards.transform, rewards.reward_keys)


def test_episode_steps_reads_the_env_time_limit_else_the_default():
    env = ToyHandEnv()
    assert episode_steps(env) == env.time_limit
    no_limit = TransformedEnv(ToyHandEnv())  # a wrapper that names no time_limit of its own
    assert episode_steps(no_limit, default=17) == 17


class SpecEnv(EnvBase):
    """Specs only: ``observation_spec`` as given (leading ``batch_size``), a 2-d action."""

    def __init__(self, observation_spec: Composite, batch_size: tuple[int, ...] = ()) -> None:
        super().__init__(device="cpu", batch_size=torch.Size(batch_size))
        self.observation_spec = observation_spec
        self.action_spec = Unbounded((*batch_size, 2))

    def _reset(self, tensordict=None):
        raise NotImplementedError

    def _step(self, tensordict):
        raise NotImplementedError

    def _set_seed(self, seed):
        return seed


def _relabelled_hand() -> TransformedEnv:
    """The toy hand with dm_control's names (``position``, ``velocity``: no ``joint_pos``) and
    its ``observation`` concatenated from them, after another concatenation (``effort``)."""
    return TransformedEnv(
        ToyHandEnv(),
        Compose(
            RenameTransform(["joint_pos", "joint_vel"], ["position", "velocity"]),
            CatTensors(["velocity", "actuator_force"], "effort", del_keys=False),
            ExcludeTransform("observation"),
            CatTensors(["position", "velocity"], "observation", del_keys=False),
        ),
    )


def test_the_observations_sources_are_the_in_keys_of_the_concatenation_that_writes_it():
    env = _relabelled_hand()
    assert observation_sources(env) == ["position", "velocity"]
    assert observation_sources(env, "effort") == ["actuator_force", "velocity"]  # sorted
    assert observation_sources(env, "touch") == []  # no concatenation writes it
    assert observation_sources(ToyHandEnv()) == []  # no transform at all
    # the dynamics model's groups: the concatenated entries, where the hand's are absent
    assert env_sizes(env, keys.OBSERVATION, keys.TOUCH) == (
        48, 20, {"position": (24,), "velocity": (24,)},
    )  # fmt: skip
    assert env_feature_shapes(ToyHandEnv()) == {
        keys.JOINT_POS: (24,), keys.JOINT_VEL: (24,), keys.TOUCH: (5, 3),
    }  # fmt: skip


def test_without_the_hands_groups_or_a_concatenation_the_model_predicts_the_observation_key():
    spec = Composite(state=Unbounded((5,)), force=Unbounded((3, 1)), observation=Unbounded((7,)))
    assert env_sizes(SpecEnv(spec), "state", "force") == (5, 2, {"state": (5,)})


def test_a_batched_env_is_sized_per_env():
    spec = Composite(observation=Unbounded((4, 5)), touch=Unbounded((4, 3, 1)), shape=(4,))
    assert env_sizes(SpecEnv(spec, (4,)), keys.OBSERVATION, keys.TOUCH) == (
        5, 2, {keys.TOUCH: (3, 1)},
    )  # fmt: skip


def _nested() -> SpecEnv:
    return SpecEnv(
        Composite(
            observation=Unbounded((5,)),
            hand=Composite(touch=Unbounded((3, 1)), angle=Unbounded((2,))),
        )
    )


def test_a_nested_force_entry_is_found_and_a_group_of_entries_is_no_force():
    assert env_sizes(_nested(), keys.OBSERVATION, ("hand", "touch"))[:2] == (5, 2)
    with pytest.raises(KeyError) as refused:
        env_sizes(_nested(), keys.OBSERVATION, "hand")
    assert refused.value.args[0] == (
        "IntrinsicRewards.from_env: force_key='hand' is not in the env's observation spec, "
        """which has ["('hand', 'angle')", "('hand', 'touch')", 'observation']"""
    )
    with pytest.raises(KeyError) as refused:
        env_sizes(_nested(), "state", ("hand", "touch"))
    assert "from_env: obs_key='state' is not in the env's observation spec" in refused.value.args[0]


def test_an_observation_that_is_no_flat_vector_is_refused_naming_the_fix():
    spec = Composite(pixels=Unbounded((3, 8)), touch=Unbounded((3, 1)))
    with pytest.raises(
        ValueError,
        match=r"^IntrinsicRewards.from_env: 'pixels' must be a flat float vector \[obs_dim\], got "
        r"\(3, 8\) torch.float32 \(an image or a dict needs an encoder or CatTensors first\)$",
    ):
        env_sizes(SpecEnv(spec), "pixels", keys.TOUCH)


def _paper_transform():
    return IntrinsicRewards(
        "r+rf", GentlenessConfig(), obs_dim=63, action_dim=20, feature_shapes={}
    ).transform


def test_checking_a_transformed_env_neither_warns_nor_changes_it(monkeypatch):
    from torchrl.envs.transforms import _base

    # TorchRL warns once per process that it unwraps a TransformedEnv given to another
    monkeypatch.setattr(_base, "_AUTO_UNWRAP_WARNING_EMITTED", False)
    env = _relabelled_hand()
    before = env.rollout(3, break_when_any_done=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. TorchRL's "nested TransformedEnvs are unwrapped"
        check_env_keys(env, _paper_transform(), ["reward", "penalty"])
    assert len(env.transform) == 4 and type(env.base_env) is ToyHandEnv
    after = env.rollout(3, break_when_any_done=False)
    assert set(after.keys(True, True)) == set(before.keys(True, True))
    assert after["observation"].shape == (3, 48)


def test_a_dict_observation_is_no_observation_and_the_produced_entries_are_listed():
    env = SpecEnv(Composite(observation=Composite(pos=Unbounded((3,))), touch=Unbounded((5, 3))))
    env.full_reward_spec = Composite(reward=Unbounded((1,)), bonus=Composite(tip=Unbounded((1,))))
    with pytest.raises(ValueError) as refused:
        check_env_keys(env, _paper_transform(), ["reward", "penalty", "bonus"])
    assert str(refused.value) == (
        "key(s) ['observation', 'bonus'] needed by the run are produced neither by the env nor "
        "by the reward transforms (produced: [\"('bonus', 'tip')\", \"('observation', 'pos')\", "
        "'impact', 'penalty', 'reward', 'touch'])"
    )


def test_a_transform_refusing_the_envs_spec_is_named_with_the_envs_observations():
    env = SpecEnv(Composite(observation=Unbounded((5,)), hand=Composite(touch=Unbounded((5, 3)))))
    with pytest.raises(ValueError) as refused:
        check_env_keys(env, SumRewards(["reward", "bonus"]), ["reward"])
    assert str(refused.value) == (
        "the env does not produce \"SumRewards sums ['bonus'], which the env's reward spec "
        "lacks; it has ['reward'] (append the reward transforms first)\" that the reward "
        "transforms read (env observation keys: [\"('hand', 'touch')\", 'observation'])"
    )


class TimedEnv(SpecEnv):
    """An env whose class names its episode length as a property (a wrapper's)."""

    @property
    def time_limit(self) -> int:
        return 77


def test_episode_steps_reads_a_time_limit_property_and_defaults_to_1000():
    spec = Composite(observation=Unbounded((5,)))
    assert episode_steps(TimedEnv(spec)) == 77
    assert episode_steps(SpecEnv(spec)) == 1000


def test_the_dynamics_groups_are_the_sources_of_the_observation_key_given():
    assert env_feature_shapes(_relabelled_hand(), "effort") == {
        "actuator_force": (20,), "velocity": (24,),
    }  # fmt: skip
