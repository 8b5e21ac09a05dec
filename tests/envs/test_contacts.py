"""``ContactForces`` (``gentlerl.envs.contacts``): MuJoCo's contact forces summed per named group,
checked against physics (a resting box weighs m g, a box held on an incline by friction), on
dm_control's walker and Gymnasium's Hopper through ``make_external_env``, and in the config."""

import math

import mujoco
import numpy as np
import pytest
import torch
from hydra import compose, initialize
from tensordict import TensorDict
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import check_env_specs

from gentlerl import keys
from gentlerl.apps.train import config_from_hydra, register_configs
from gentlerl.envs.contacts import (
    CONTACT_GROUPS,
    ContactForces,
    contact_forces,
    group_forces,
    resolve_groups,
)
from gentlerl.envs.external import FORCE_ADAPTERS, adapt_env, make_external_env
from gentlerl.training.builders import default_env_factory
from gentlerl.training.config import make_config
from gentlerl.transforms import ImpactPenalty

G = 9.81

#: Two free boxes side by side on a plane (1 kg and 3 kg), and a free "leg" whose only geom in
#: reach of the floor is its child body's "foot" (2 kg in all).
BOXES = """
<mujoco>
  <option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="box_a" pos="0 0 {za}">
      <freejoint/>
      <geom name="box_a" type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
    <body name="box_b" pos="1 0 0.099">
      <freejoint/>
      <geom name="box_b" type="box" size="0.1 0.1 0.1" mass="3"/>
    </body>
    <body name="leg" pos="-1 0 0.599">
      <freejoint/>
      <geom name="shin" type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="1"/>
      <body name="foot" pos="0 0 -0.5">
        <geom name="sole" type="box" size="0.1 0.1 0.1" mass="1"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

#: A 1 kg box on a plane tilted by 20 degrees, friction 1 > tan 20: static friction holds it.
INCLINE = """
<mujoco>
  <option timestep="0.002" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="ramp" type="plane" size="5 5 0.1" euler="0 20 0" friction="1 0.005 0.0001"/>
    <body name="box" pos="0 0 0.2" euler="0 20 0">
      <freejoint/>
      <geom name="box" type="box" size="0.1 0.1 0.1" mass="1" friction="1 0.005 0.0001"/>
    </body>
  </worldbody>
</mujoco>
"""


class MjcfEnv(EnvBase):
    """A TorchRL env stepping an MJCF model (``substeps`` physics steps per step; the action is
    ignored), holding ``model`` and ``data`` as the contacts adapter reads them."""

    def __init__(self, xml: str, substeps: int = 50) -> None:
        super().__init__(batch_size=torch.Size([]))
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self.substeps = substeps
        self.observation_spec = Composite(qpos=Unbounded((self.model.nq,), dtype=torch.float64))
        self.action_spec = Bounded(-1.0, 1.0, (1,), dtype=torch.float64)
        self.reward_spec = Unbounded((1,), dtype=torch.float64)
        flag = Categorical(2, (1,), dtype=torch.bool)
        self.full_done_spec = Composite(
            done=flag.clone(), terminated=flag.clone(), truncated=flag.clone()
        )

    def _obs(self) -> TensorDict:
        return TensorDict({"qpos": torch.as_tensor(self.data.qpos.copy())}, [])

    def _reset(self, tensordict=None):
        mujoco.mj_resetData(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        return self._obs()

    def _step(self, tensordict):
        mujoco.mj_step(self.model, self.data, self.substeps)
        out = self._obs()
        out["reward"] = torch.zeros(1, dtype=torch.float64)
        for key in ("done", "terminated", "truncated"):
            out[key] = torch.zeros(1, dtype=torch.bool)
        return out

    def _set_seed(self, seed):
        pass


def _boxes(za: float = 0.1, substeps: int = 50) -> MjcfEnv:
    return MjcfEnv(BOXES.format(za=za), substeps)


def test_a_resting_box_weighs_m_g_and_groups_sum_their_bodies():
    groups = {"a": ["box_a"], "b": ["body:box_b"], "both": ["box_a", "geom:box_b"]}
    groups |= {"leg": ["leg"], "leg_subtree": ["subtree:leg"], "foot": ["foot"]}
    env = TransformedEnv(_boxes(), ContactForces(groups))
    check_env_specs(env)
    td = env.rollout(20)  # 20 x 50 x 2 ms = 2 s: settled
    force = td["next", "force"][-1, :, 0]
    assert td["next", "force"].shape == (20, 6, 1) and force.dtype == torch.float32
    a, b, both, leg, leg_subtree, foot = force.tolist()
    assert a == pytest.approx(1 * G, rel=0.01)
    assert b == pytest.approx(3 * G, rel=0.01)
    assert both == pytest.approx(a + b, rel=1e-6)
    # a body is its own geoms: the leg's shin never touches; its subtree stands on the foot
    assert leg == 0.0
    assert leg_subtree == pytest.approx(2 * G, rel=0.01) and foot == pytest.approx(leg_subtree)


def test_normal_and_total_force_on_an_incline_held_by_friction():
    env = MjcfEnv(INCLINE)
    env.reset()
    mujoco.mj_step(env.model, env.data, 1500)  # 3 s: at rest
    assert env.data.ncon > 0 and abs(env.data.qvel).max() < 1e-2  # a soft contact creeps
    member = resolve_groups(env.model, {"box": ["box"]})
    normal = group_forces(env.model, env.data, member, "normal")[0]
    total = group_forces(env.model, env.data, member, "total")[0]
    # the plane pushes back with N = m g cos 20; with friction the whole force is m g
    assert normal == pytest.approx(G * math.cos(math.radians(20)), rel=0.01)
    assert total == pytest.approx(G, rel=0.01)
    # MuJoCo's own reading per contact
    reading = torch.zeros(6, dtype=torch.float64).numpy()
    geom1, geom2, per_contact = contact_forces(env.model, env.data, "normal")
    for i, f in enumerate(per_contact):
        mujoco.mj_contactForce(env.model, env.data, i, reading)
        assert f == reading[0]
    assert len(geom1) == len(geom2) == env.data.ncon


@pytest.mark.parametrize("component", ["normal", "total"])
def test_group_sums_match_the_contact_by_contact_reading_on_walker(component):
    """The loop of ``group_forces`` against numpy over every contact of a random walker run:
    a contact counts once per group holding either of its geoms."""
    from dm_control import suite

    env = suite.load("walker", "walk", task_kwargs={"random": 0})
    model, data = env.physics.model.ptr, env.physics.data.ptr
    groups = {"r": ["right_foot"], "l": ["left_foot"], "feet": ["left_foot", "right_foot"]}
    member = resolve_groups(model, groups | {"all": ["subtree:torso"], "floor": ["floor"]})
    rng, seen = torch.Generator().manual_seed(0), 0
    env.reset()
    for _ in range(300):
        env.step(torch.rand(6, generator=rng).numpy() * 2 - 1)
        geom1, geom2, force = contact_forces(model, data, component)
        expected = (member[geom1] | member[geom2]).T.astype(float) @ force
        got = group_forces(model, data, member, component)
        assert got == pytest.approx(expected, rel=1e-12, abs=1e-9)
        seen += data.ncon
    assert seen > 100
    # the floor group holds every contact: the whole body's and the floor's sums agree
    assert got[3] == pytest.approx(got[4]) and got[2] == pytest.approx(got[0] + got[1])


def test_reset_writes_the_contacts_it_leaves_or_zeros():
    # box_a dropped from 1 m (4 ms steps): nothing of group "a" touches at the reset
    groups = ContactForces({"a": ["box_a"], "b": ["box_b"]})
    dropped = TransformedEnv(_boxes(za=1.0, substeps=2), groups)
    reset = dropped.reset()
    assert reset["force"][0, 0] == 0.0 and reset["force"][1, 0] > 0.0  # box_b rests already
    zeros = TransformedEnv(_boxes(), ContactForces({"b": ["box_b"]}, reset_zeros=True))
    assert zeros.reset()["force"].abs().sum() == 0.0
    # it lands after 0.45 s: a strike above its weight on "a"; "b" rests from its reset on, so
    # its first step is no impact (zeros at the reset would make its weight one)
    dropped.append_transform(ImpactPenalty(in_keys=["force"]))
    impact = dropped.rollout(250)["next", keys.IMPACT]
    assert impact[:, 0].max() > 3 * G and impact[:, 1].max() < 0.2 * G


def test_group_names_are_checked_with_one_line_errors():
    model = _boxes().model
    with pytest.raises(ValueError, match=r"'box_c' is no body of the model; bodies: \['world'"):
        resolve_groups(model, {"c": ["box_c"]})
    with pytest.raises(ValueError, match=r"'sol' is no geom of the model; geoms: \['box_a'"):
        resolve_groups(model, {"c": ["geom:sol"]})
    with pytest.raises(ValueError, match="must list body or geom names"):
        resolve_groups(model, {"c": "box_a"})
    with pytest.raises(ValueError, match="must map a group name"):
        resolve_groups(model, {})
    assert resolve_groups(model, {"s": ["sole"]}).sum() == 1  # a bare geom name
    env = TransformedEnv(_boxes(), ContactForces({"c": ["box_c"]}))
    with pytest.raises(ValueError, match="'box_c' is no body"):
        env.transform.bind()
    with pytest.raises(ValueError, match=r"reads one simulator: append it to an unbatched env"):
        ContactForces({"a": ["box_a"]}).transform_observation_spec(Composite(shape=(2,)))


def test_walker_gets_its_feet_as_force_sites_and_passes_the_spec_check():
    env = make_external_env("dm_control:walker-walk", seed=0)
    check_env_specs(env)
    assert env.observation_spec["force"].shape == (2, 1)
    assert list(env.transform[1].groups) == list(CONTACT_GROUPS["dm_control:walker"])
    torch.manual_seed(0)
    td = env.rollout(200)
    assert td["next", "force"].max() > 100.0  # a foot landing carries the walker's 280 N
    assert env.observation_spec[keys.OBSERVATION].shape == (24,)  # force is not observed
    # finger keeps its touch sensors
    finger = make_external_env("dm_control:finger-spin", seed=0)
    assert not any(isinstance(t, ContactForces) for t in finger.transform)
    # named groups (a subtree: the whole walker)
    body = make_external_env("dm_control:walker-walk", force_groups={"all": ["subtree:torso"]})
    assert body.observation_spec["force"].shape == (1, 1)


def test_gymnasium_hopper_through_the_gym_source():
    env = make_external_env("gym:Hopper-v5", seed=0)
    check_env_specs(env)
    assert env.time_limit == 1000 and env.observation_spec[keys.OBSERVATION].shape == (11,)
    torch.manual_seed(0)
    td = env.rollout(50)
    # the hopper (15.8 kg: 155 N) drops onto its foot within 50 steps: a strike above its weight
    assert td["next", "force"].max() > 155.0


def test_adapter_and_config_errors_name_the_fix():
    with pytest.raises(ValueError, match=r"needs force groups; set env.force_groups=.*'box_a'"):
        adapt_env(_boxes(), force_adapter="contacts")
    with pytest.raises(ValueError, match="apply to the contacts adapter, not to 'none'"):
        adapt_env(_boxes(), force_adapter="none", force_groups={"a": ["box_a"]})
    env = adapt_env(_boxes(), force_adapter="contacts", force_groups={"a": ["box_a"]})
    assert env.observation_spec["force"].shape == (1, 1) and FORCE_ADAPTERS["contacts"].groups
    with pytest.raises(ValueError, match=r"'rigth_foot' is no body of the model; bodies: \["):
        make_config(env={"name": "dm_control:walker-walk", "force_groups": {"f": ["rigth_foot"]}})
    with pytest.raises(ValueError, match="acrobot-swingup has no default groups; set env.force"):
        make_config(env={"name": "dm_control:acrobot-swingup"})
    with pytest.raises(ValueError, match="not to env.force_adapter='dm_control_touch'"):
        make_config(
            env={
                "name": "dm_control:finger-spin",
                "force_adapter": "dm_control_touch",
                "force_groups": {"tip": ["distal"]},
            }
        )
    with pytest.raises(ValueError, match="Gymnasium has no env Hopper-v9; known: .*'Hopper-v5'"):
        make_config(env={"name": "gym:Hopper-v9"})
    cfg = make_config(env={"name": "dm_control:cheetah-run", "force_groups": {"f": ["ffoot"]}})
    assert cfg.env.force_groups == {"f": ["ffoot"]}


def test_the_train_command_line_names_force_groups():
    register_configs()
    overrides = ["env.name=dm_control:walker-walk", "+env.force_groups.feet=[left_foot,right_foot]"]
    with initialize(version_base="1.3", config_path=None):
        cfg = config_from_hydra(compose("gentlerl_train", overrides=overrides))
    assert cfg.env.force_groups == {"feet": ["left_foot", "right_foot"]}
    env = default_env_factory(cfg)()
    assert env.observation_spec["force"].shape == (1, 1)  # both feet summed into one site


def test_the_loop_trains_on_gymnasium_hopper_with_contact_forces(tmp_path):
    from gentlerl.training.loop import train

    cfg = make_config(
        variant="r+rf+rsp",
        run_dir=str(tmp_path / "run"),
        env={"name": "gym:Hopper-v5", "force_scale": 0.01},
        collector={"total_frames": 120, "frames_per_batch": 40, "init_random_frames": 40},
        replay={"batch_size": 8, "n_steps": 2},
        gentleness={"reward_delay": 5, "model_batch_size": 8, "ensemble_size": 2},
        network={"actor_hidden": [8], "critic_hidden": [8], "num_atoms": 11},
        logging={"eval_every_frames": 120, "eval_episodes": 1, "progress": False},
    )
    summary = train(cfg)
    # judged by its return (no success); a fall onto the foot is an impact (in N x 0.01)
    assert "success_rate" not in summary and summary["max_impact_mean"] > 0.0
    assert math.isfinite(summary["return"])


def test_every_default_group_names_its_envs_bodies():
    from gentlerl.envs.external import mujoco_model

    tasks = {"walker": "walk", "cheetah": "run", "hopper": "hop", "ball_in_cup": "catch"}
    tasks |= {"humanoid": "walk", "quadruped": "walk"}
    for key, groups in CONTACT_GROUPS.items():
        source, _, model = key.partition(":")
        name = f"{key}-{tasks[model]}" if source == "dm_control" else f"{key}-v5"
        name = "manipulation:lift_brick_features" if source == "manipulation" else name
        member = resolve_groups(mujoco_model(name), groups)
        assert member.any(0).all(), key  # each group holds a geom


def test_dm_control_manipulation_through_the_composer_source():
    env = make_external_env("manipulation:lift_brick_features", seed=3)
    again = make_external_env("manipulation:lift_brick_features", seed=3)
    torch.testing.assert_close(env.reset()[keys.OBSERVATION], again.reset()[keys.OBSERVATION])
    check_env_specs(env)
    # the Jaco hand's three fingers; composer observables [1, n] flattened into observation
    assert env.observation_spec["force"].shape == (3, 1) and env.time_limit == 250
    assert env.observation_spec[keys.OBSERVATION].shape == (55,)
    with pytest.raises(
        ValueError, match="manipulation has no env lift_brik; known: \\['lift_brick"
    ):
        make_config(env={"name": "manipulation:lift_brik"})


def test_after_a_dm_control_step_the_forces_are_read_of_one_state_and_the_run_is_untouched():
    """The finding: dm_control's step leaves efc_force of the step before against the new
    contacts; read as it is, walker's contact normals came out negative (31 of 341). Read
    through settled(): never negative, and the env's own data is not changed."""
    from dm_control import suite

    from gentlerl.envs.contacts import contact_forces, settled

    env = suite.load("walker", "walk", task_kwargs={"random": 0})
    model, data = env.physics.model.ptr, env.physics.data.ptr
    rng, scratch, normals, stale = np.random.default_rng(0), None, [], []
    env.reset()
    for _ in range(150):
        env.step(rng.uniform(-1, 1, 6))
        stale += contact_forces(model, data)[2].tolist()
        before = (data.qacc.copy(), data.efc_force.copy())
        scratch = settled(model, data, scratch)
        normals += contact_forces(model, scratch)[2].tolist()
        assert np.array_equal(data.qacc, before[0]) and np.array_equal(data.efc_force, before[1])
    assert len(normals) > 50 and min(normals) >= 0.0
    assert min(stale) < 0.0  # what the adapter read before
