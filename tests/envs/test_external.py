"""External TorchRL envs (``gentlerl.envs.external``): dm_control's finger through the adapters,
a scripted float64 env with known forces, an observation that is not called ``observation``, the
config fields and a run through the training loop on an env without success / broken."""

import math

import pytest
import torch
from hydra import compose, initialize
from tensordict import TensorDict
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import Compose, DoubleToFloat, EnvBase, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.agent.builder import AgentBuilder
from gentlerl.analysis.runs import find_runs
from gentlerl.analysis.summary import summary_table
from gentlerl.apps.evaluate import evaluate_policy
from gentlerl.apps.train import config_from_hydra, register_configs
from gentlerl.config import GentlenessConfig
from gentlerl.envs.external import FORCE_ADAPTERS, adapt_env, make_external_env
from gentlerl.models import make_actor
from gentlerl.rewards import IntrinsicRewards
from gentlerl.training import save_checkpoint
from gentlerl.training.builders import default_env_factory
from gentlerl.training.config import make_config
from gentlerl.training.evaluation import rank, summarize_episodes
from gentlerl.training.logging import EpisodeStats
from gentlerl.training.loop import train
from gentlerl.transforms import ImpactPenalty

#: Sensor readings (N) of the scripted env's 2 sites at steps 0, 1, 2, ... (cyclic).
READINGS = torch.tensor([[0.0, 0.0], [3.0, 1.0], [3.0, 4.0], [0.0, 0.0]], dtype=torch.float64)


class ScriptedTouchEnv(EnvBase):
    """dm_control-like: float64 everywhere, ``touch`` [2] = log1p(:data:`READINGS`), a position
    that integrates the action, no ``observation`` / ``success`` / ``broken``; ends after
    ``length`` steps. ``obs_key`` renames ``position`` (a non-default observation name)."""

    def __init__(self, length: int = 8, obs_key: str = "position") -> None:
        super().__init__(batch_size=torch.Size([]))
        self.length, self.obs_key = length, obs_key
        f64 = torch.float64
        self.observation_spec = Composite(
            {obs_key: Unbounded((2,), dtype=f64), keys.TOUCH: Unbounded((2,), dtype=f64)}
        )
        self.action_spec = Bounded(-1.0, 1.0, (2,), dtype=f64)
        self.reward_spec = Unbounded((1,), dtype=f64)
        flag = Categorical(2, (1,), dtype=torch.bool)
        self.full_done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone()
        )

    def _obs(self) -> dict[str, torch.Tensor]:
        reading = READINGS[self._t % len(READINGS)]
        return {self.obs_key: self._pos.clone(), keys.TOUCH: torch.log1p(reading)}

    def _reset(self, tensordict=None):
        self._pos, self._t = torch.zeros(2, dtype=torch.float64), 0
        return TensorDict(self._obs(), [])

    def _step(self, tensordict):
        self._t += 1
        self._pos = self._pos + 0.1 * tensordict[keys.ACTION]
        end = torch.tensor([self._t >= self.length])
        reward = -self._pos.abs().sum(-1, keepdim=True)
        out = {**self._obs(), keys.REWARD: reward, "done": end, "terminated": end.clone()}
        return TensorDict({**out, "truncated": torch.zeros(1, dtype=torch.bool)}, [])

    def _set_seed(self, seed):
        torch.manual_seed(seed or 0)


class ContactEnv(ScriptedTouchEnv):
    """:class:`ScriptedTouchEnv` with its reading also as ``contact`` [2, 1], in the layout the
    rewards read."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_spec["contact"] = Unbounded((2, 1), dtype=torch.float64)

    def _obs(self) -> dict[str, torch.Tensor]:
        obs = super()._obs()
        return {**obs, "contact": obs[keys.TOUCH].unsqueeze(-1)}


def test_finger_spin_env_is_float32_with_force_in_newtons_and_a_flat_observation():
    env = make_external_env("dm_control:finger-spin", seed=0)
    check_env_specs(env)
    spec = env.observation_spec
    assert spec[keys.OBSERVATION].shape == (9,)  # position 4 + velocity 3 + touch 2
    assert spec["force"].shape == (2, 1) and env.time_limit == 1000
    torch.manual_seed(1)  # random actions (torch's generator): this one strikes the spinner
    td = env.rollout(300)
    assert td[keys.OBSERVATION].dtype == td["force"].dtype == torch.float32
    torch.testing.assert_close(
        td[keys.OBSERVATION], torch.cat([td["position"], td["velocity"], td["touch"]], -1)
    )
    torch.testing.assert_close(td["next", "force"][..., 0], torch.expm1(td["next", "touch"]))
    assert td["next", "force"].max() > 10.0  # tens of N in a strike
    with_impact = TransformedEnv(env, ImpactPenalty(in_keys=["force"]))
    check_env_specs(with_impact)


def test_dm_control_float64_is_cast_to_float32_at_the_boundary():
    env = make_external_env("dm_control:finger-spin", seed=0)
    raw = env.base_env
    assert raw.observation_spec["position"].dtype == torch.float64
    assert raw.action_spec.dtype == raw.reward_spec.dtype == torch.float64
    assert env.action_spec.dtype == env.reward_spec.dtype == torch.float32
    td = env.rollout(3)
    floats = [v for v in td.values(True, True) if v.is_floating_point()]
    assert floats and all(v.dtype == torch.float32 for v in floats)


def test_adapter_turns_known_log1p_readings_into_the_impacts_of_eq_1():
    env = adapt_env(ScriptedTouchEnv())
    check_env_specs(env)
    td = TransformedEnv(env, ImpactPenalty(lam=(2.0, 2.0), in_keys=["force"])).rollout(3)
    # readings [0,0] -> [3,1] -> [3,4] -> [0,0]: m = max(0, f_{t+1} - f_t) per site, 1 channel
    expected_impact = torch.tensor([[3.0, 1.0], [0.0, 3.0], [0.0, 0.0]])
    torch.testing.assert_close(td["next", keys.IMPACT], expected_impact)
    # eq. 4, lambda = (2, 2): -(1 - sigmoid(2 (2 - m))) m: 3 N -> -2.6424, 1 N -> -0.1192
    torch.testing.assert_close(
        td["next", keys.PENALTY].squeeze(-1), torch.tensor([-2.7616, -2.6424, 0.0]), atol=1e-4,
        rtol=0,
    )  # fmt: skip
    # observation = position, touch (spec order), float32
    assert td[keys.OBSERVATION].shape == (3, 4) and td[keys.OBSERVATION].dtype == torch.float32


def test_force_scale_changes_the_unit_of_the_force_the_rewards_read_not_the_observation():
    # Hundredths: readings [0,0] -> [3,1] -> [3,4] N read as [0.03, 0.01] -> [0.03, 0.04].
    env = TransformedEnv(
        adapt_env(ScriptedTouchEnv(), force_scale=0.01), ImpactPenalty(in_keys=["force"])
    )
    check_env_specs(env)
    td = env.rollout(3)
    torch.testing.assert_close(td["next", "force"][1, :, 0], torch.tensor([0.03, 0.04]))
    torch.testing.assert_close(
        td["next", keys.IMPACT], torch.tensor([[0.03, 0.01], [0.0, 0.03], [0.0, 0.0]])
    )
    # the observation keeps the env's own reading, log1p of newtons
    torch.testing.assert_close(td["next", "touch"][1], torch.log1p(torch.tensor([3.0, 4.0])))
    # also where the force is one of the env's own observation entries (adapter "none")
    own = adapt_env(
        ContactEnv(), force_adapter="none", force_key="contact",
        observation_keys=["position", "touch"], force_scale=0.5,
    )  # fmt: skip
    step = own.rollout(3)["next"][1]
    torch.testing.assert_close(step[keys.OBSERVATION][-2:], torch.log1p(torch.tensor([3.0, 4.0])))
    torch.testing.assert_close(step["contact"][:, 0], 0.5 * torch.log1p(torch.tensor([3.0, 4.0])))
    cfg = make_config(env={"name": "dm_control:finger-spin", "force_scale": 0.01})
    torch.manual_seed(1)
    scaled = default_env_factory(cfg)().rollout(300)
    torch.testing.assert_close(
        scaled["next", "force"][..., 0], 0.01 * torch.expm1(scaled["next", "touch"])
    )
    for bad in (0.0, -1.0, float("inf")):
        with pytest.raises(ValueError, match="force_scale must be a finite number > 0"):
            adapt_env(ScriptedTouchEnv(), force_scale=bad)
    with pytest.raises(ValueError, match="env.force_scale=0.5 applies to an external env only"):
        make_config(env={"force_scale": 0.5})
    with pytest.raises(ValueError, match="env.force_scale=0 must be > 0"):
        make_config(env={"name": "dm_control:finger-spin", "force_scale": 0})


def test_adapter_errors_name_what_is_missing():
    with pytest.raises(ValueError, match="unknown force adapter 'nope'"):
        adapt_env(ScriptedTouchEnv(), force_adapter="nope")
    with pytest.raises(ValueError, match=r"observation key\(s\) \['speed'\]"):
        adapt_env(ScriptedTouchEnv(), observation_keys=["speed"])
    with pytest.raises(ValueError, match=r"force key 'force' \(env.force_key\) is not written"):
        adapt_env(ScriptedTouchEnv(), force_adapter="none")
    # an entry without its channel dim: [2], not [n_sites, n_channels]
    with pytest.raises(ValueError, match=r"force key 'touch' \(env.force_key\) has shape \[2\]"):
        adapt_env(ScriptedTouchEnv(), force_adapter="none", force_key="touch")
    assert set(FORCE_ADAPTERS) >= {"dm_control_touch", "none"}


def test_intrinsic_rewards_read_an_observation_key_that_is_not_observation():
    env = TransformedEnv(
        ScriptedTouchEnv(obs_key="state"),
        Compose(DoubleToFloat(), *FORCE_ADAPTERS["dm_control_touch"].build("touch", "force")),
    )
    settings = GentlenessConfig(reward_delay=0)
    default = IntrinsicRewards("r+rf+rsp", settings, obs_dim=2, action_dim=2,
                               feature_shapes={}, force_key="force")  # fmt: skip
    batch = env.rollout(4)
    with pytest.raises(KeyError, match=r"'observation' \(obs_key\).*pass obs_key="):
        default.transform(batch.clone())
    rewards = IntrinsicRewards("r+rf+rsp", settings, obs_dim=2, action_dim=2,
                               feature_shapes={}, force_key="force", obs_key="state")  # fmt: skip
    rewards.step(1)  # past the reward delay of 0: the surprise is on
    out = rewards.transform(batch)
    penalty, surprise = out["next", keys.PENALTY], out["next", keys.PENALTY_SURPRISE]
    torch.testing.assert_close(penalty.squeeze(-1), torch.tensor([-2.7616, -2.6424, 0.0, 0.0]),
                               atol=1e-4, rtol=0)  # fmt: skip
    assert (surprise[penalty < 0] != 0).all() and (surprise[penalty == 0] == 0).all()  # eq. 8
    rewards.extend(out)
    assert set(rewards.update(2)) == {"model_penalty"}  # the model trains on "state"


def test_the_force_penalty_variant_reads_the_configured_force_key():
    env = adapt_env(ScriptedTouchEnv())
    rewards = IntrinsicRewards("r+rf+rsp+rF", GentlenessConfig(), obs_dim=4, action_dim=2,
                               feature_shapes={}, force_key="force")  # fmt: skip
    out = rewards.transform(env.rollout(3))
    # r^F = -sum_i (1 - sigmoid(2 (8 - F_i))) F_i over the next readings [3, 1], [3, 4], [0, 0]
    total = torch.tensor([[3.0, 1.0], [3.0, 4.0], [0.0, 0.0]])
    expected = -((1 - torch.sigmoid(2 * (8 - total))) * total).sum(-1, keepdim=True)
    torch.testing.assert_close(out["next", keys.FORCE_PENALTY], expected)
    assert out["next", keys.FORCE_PENALTY][1].item() == pytest.approx(-1.478e-3, rel=1e-3)


def test_config_names_the_external_env_and_validates_its_fields():
    cfg = make_config(env={"name": "dm_control:finger-spin"})
    assert cfg.env.force == "force" and make_config().env.force == "touch"
    env = default_env_factory(cfg)()
    builder = AgentBuilder(cfg, env)
    assert (builder.obs_dim, builder.action_dim, builder.horizon) == (9, 2, 1000)
    assert builder.feature_shapes == {"position": (4,), "velocity": (3,), "touch": (2,)}
    assert builder.rewards.force_key == "force"
    bad = {"name": "dm_control:finger-fly", "force_adapter": "nope"}
    with pytest.raises(ValueError) as err:
        make_config(env=bad)
    assert "no task finger-fly; known: ['finger-spin', 'finger-turn_easy'" in str(err.value)
    assert "env.force_adapter='nope' is not one of" in str(err.value)
    with pytest.raises(ValueError, match="must read 'dm_control:<domain>-<task>'.* or 'gym:<"):
        make_config(env={"name": "finger-spin"})
    with pytest.raises(ValueError, match="applies to an external env only"):
        make_config(env={"force_adapter": "dm_control_touch"})


def test_the_train_command_line_names_the_finger_env():
    register_configs()
    overrides = ["env.name=dm_control:finger-spin", "env.observation_keys=[position,velocity]"]
    with initialize(version_base="1.3", config_path=None):
        cfg = config_from_hydra(compose("gentlerl_train", overrides=overrides))
    assert cfg.env.name == "dm_control:finger-spin" and cfg.env.force_adapter is None
    assert cfg.run_dir == "runs/finger-spin/r+rf+rsp/seed0"  # not under the unused hand task
    assert default_env_factory(cfg)().observation_spec[keys.OBSERVATION].shape == (7,)  # 4 + 3


def test_evaluations_without_success_are_judged_by_their_return():
    env = TransformedEnv(adapt_env(ScriptedTouchEnv(length=3)), ImpactPenalty(in_keys=["force"]))
    summary, (episode,) = summarize_episodes([env.rollout(10)])
    assert "success" not in episode and "broken" not in episode  # the env defines neither
    assert list(summary) == ["max_impact_mean", "return"]  # no success_rate=nan broken_rate=nan
    assert episode["max_impact"] == pytest.approx(3.0)  # readings [0,0] -> [3,1] -> [3,4]
    better = {**summary, "return": summary["return"] + 1.0, "max_impact_mean": 9.0}
    assert rank(better) > rank(summary)  # higher return first, whatever the impact
    stats = EpisodeStats([keys.REWARD, keys.PENALTY])
    batch = env.rollout(3)
    batch["collector", "traj_ids"] = torch.zeros(3, dtype=torch.long)
    batch["next", "episode_reward"] = batch["next", keys.REWARD].cumsum(0)
    batch["next", "step_count"] = torch.arange(1, 4).unsqueeze(-1)
    (ep,) = stats.update(batch)
    assert "success" not in ep and ep["max_impact"] == pytest.approx(3.0)
    assert ep["return_penalty"] == pytest.approx(-2.7616 - 2.6424, abs=1e-3)


def test_the_loop_trains_on_an_external_env_without_success(tmp_path):
    cfg = make_config(
        variant="r+rf+rsp",
        run_dir=str(tmp_path / "run"),
        env={"force_key": "force"},
        collector={"total_frames": 160, "frames_per_batch": 40, "init_random_frames": 40},
        replay={"batch_size": 16, "n_steps": 2},
        gentleness={"reward_delay": 5, "model_batch_size": 8, "ensemble_size": 2},
        network={"actor_hidden": [16], "critic_hidden": [16], "num_atoms": 11},
        logging={"eval_every_frames": 80, "eval_episodes": 2, "progress": False},
    )
    summary = train(cfg, env_factory=lambda: adapt_env(ScriptedTouchEnv()))
    assert "success_rate" not in summary and summary["max_impact_mean"] == pytest.approx(3.0)
    rows = (tmp_path / "run" / "eval_episodes.csv").read_text().splitlines()
    assert rows[0] == "frames,episode,max_impact,return" and len(rows) == 1 + 2 * 2
    assert "nan" not in "".join(rows)
    assert (tmp_path / "run" / "best_policy.pt").is_file()
    (row,) = summary_table(find_runs([tmp_path]))  # gentlerl plot's table: judged by return
    assert math.isnan(row["final_success"]) and row["final_median_impact"] == pytest.approx(3.0)
    assert row["final_return"] == pytest.approx(summary["return"])


def test_evaluate_runs_a_finger_policy_on_its_own_env(tmp_path):
    cfg = make_config(env={"name": "dm_control:finger-spin"}, network={"actor_hidden": (8,)})
    actor = make_actor(9, 2, cfg.network.actor_hidden)
    state = {"config": cfg.to_dict(), "obs_dim": 9, "action_dim": 2, "actor": actor.state_dict()}
    save_checkpoint(tmp_path / "policy.pt", state)
    out = evaluate_policy(tmp_path / "policy.pt", 1, episodes_csv=tmp_path / "episodes.csv")
    assert out["task"] == "dm_control:finger-spin" and "success_rate" not in out
    assert out["episodes"] == 1 and out["mean_return"] >= 0.0  # finger-spin pays 0 or 1 a step
    header, row = (tmp_path / "episodes.csv").read_text().splitlines()
    assert header == "frames,episode,max_impact,return" and "nan" not in row


def test_make_external_env_is_exported_by_the_envs_package():
    """The docs name ``make_external_env`` among ``gentlerl.envs``' public names: the package
    exports the module's function itself (lazily, as its other names)."""
    import gentlerl.envs
    from gentlerl.envs import make_external_env as exported

    assert exported is make_external_env
    assert "make_external_env" in gentlerl.envs.__all__
