"""Contact forces of any MuJoCo env, summed per named group of bodies or geoms: the force sites
of envs without touch sensors (dm_control's walker, cheetah, ball_in_cup; Gymnasium's Hopper,
Walker2d, HalfCheetah, Ant, Humanoid).

:class:`ContactForces` is a TorchRL transform. After the env's reset and after each step it reads
the simulator's contacts (``mujoco.mj_contactForce`` of each of ``data.ncon``) and writes
``force`` ``[n_groups, 1]`` in N, the ``[n_sites, n_channels]`` layout that
:class:`~gentlerl.transforms.ImpactPenalty` reads. It is the ``contacts`` force adapter of
:data:`gentlerl.envs.external.FORCE_ADAPTERS` (``env.force_adapter=contacts``,
``+env.force_groups.feet=[left_foot,right_foot]``); :data:`CONTACT_GROUPS` holds the groups an
env gets when none are named.

Names (:func:`resolve_groups`): ``NAME`` or ``body:NAME`` is a body's own geoms, not its children's
(walker's ``left_leg`` does not hold ``left_foot``: a leg and its foot are different sites);
``subtree:NAME`` is the body and every body below it (``subtree:torso``: the whole walker);
``geom:NAME`` one geom (Ant's feet are unnamed bodies with named geoms). A bare name that is no
body is tried as a geom.

A contact adds its force once to every group that holds either of its geoms (a foot on the floor;
a foot on the other foot adds to both feet's groups, once to a group holding both). Only the
simulator's last substep is read: with ``frame_skip`` > 1 (dm_control's walker steps its physics
10 times per control step) a contact that starts and ends within one control step is missed,
as the hand's touch sensors miss it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded
from torchrl.envs import Transform

if TYPE_CHECKING:
    from torchrl.envs import EnvBase

#: Where the adapter writes by default (as every force adapter: ``gentlerl.envs.external.FORCE``).
FORCE = "force"

#: What a contact's force is read as (:func:`contact_forces`).
COMPONENTS = ("normal", "total")

#: Each env's default groups (``env.force_groups`` empty), keyed ``"<source>:<model>"``: the
#: dm_control domain, or the Gymnasium id without its version (or ``"<source>"``: all its envs). Feet for the walkers and runners
#: (the feet are what strikes the ground), the ball for ball_in_cup (the ball hitting the cup).
CONTACT_GROUPS: dict[str, dict[str, tuple[str, ...]]] = {
    "dm_control:walker": {"right_foot": ("right_foot",), "left_foot": ("left_foot",)},
    "dm_control:cheetah": {"bfoot": ("bfoot",), "ffoot": ("ffoot",)},
    "dm_control:hopper": {"foot": ("foot",)},
    "dm_control:ball_in_cup": {"ball": ("ball",)},
    "dm_control:humanoid": {"right_foot": ("right_foot",), "left_foot": ("left_foot",)},
    "dm_control:quadruped": {
        "front_left": ("subtree:toe_front_left",),
        "front_right": ("subtree:toe_front_right",),
        "back_left": ("subtree:toe_back_left",),
        "back_right": ("subtree:toe_back_right",),
    },
    "gym:Hopper": {"foot": ("foot",)},
    "gym:Walker2d": {"right_foot": ("foot",), "left_foot": ("foot_left",)},
    "gym:HalfCheetah": {"bfoot": ("bfoot",), "ffoot": ("ffoot",)},
    "gym:Ant": {
        "front_left": ("geom:left_ankle_geom",),
        "front_right": ("geom:right_ankle_geom",),
        "back": ("geom:third_ankle_geom",),
        "right_back": ("geom:fourth_ankle_geom",),
    },
    "gym:Humanoid": {"right_foot": ("right_foot",), "left_foot": ("left_foot",)},
    # every dm_control.manipulation env: the Jaco hand's three fingers, each with its tip
    "manipulation": {
        f"finger_{i}": (f"subtree:jaco_arm/jaco_hand/b_finger_{i}",) for i in (1, 2, 3)
    },
}


def default_groups(name: str) -> dict[str, tuple[str, ...]] | None:
    """:data:`CONTACT_GROUPS` of the env ``name`` (``"dm_control:walker-walk"``,
    ``"gym:Hopper-v5"``), or ``None``."""
    source, _, spec = name.partition(":")
    model = spec.partition("-")[0]
    return CONTACT_GROUPS.get(f"{source}:{model}", CONTACT_GROUPS.get(source))


def _names(model: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> list[str | None]:
    return [mujoco.mj_id2name(model, kind, i) for i in range(count)]


def resolve_groups(model: mujoco.MjModel, groups: Mapping[str, Sequence[str]]) -> np.ndarray:
    """``member`` ``[ngeom, n_groups]``: whether each geom of ``model`` is in each group.

    ``groups`` maps a group's name to the bodies and geoms it holds (the module's rule: ``NAME``
    or ``body:NAME`` a body's own geoms, ``subtree:NAME`` with its descendants, ``geom:NAME``).
    A one-line ``ValueError`` names an unknown name and lists the model's bodies (or geoms).
    """
    if not isinstance(groups, Mapping) or not groups:
        raise ValueError(f"force groups must map a group name to names, got {groups!r}")
    bodies = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody)
    geoms = _names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)
    body_ids = {n: i for i, n in enumerate(bodies) if n}
    geom_ids = {n: i for i, n in enumerate(geoms) if n}
    parents = np.asarray(model.body_parentid)
    member = np.zeros((model.ngeom, len(groups)), dtype=bool)
    for column, (group, names) in enumerate(groups.items()):
        if isinstance(names, str) or not isinstance(names, Sequence) or not names:
            raise ValueError(f"force group {group!r} must list body or geom names, got {names!r}")
        for name in names:
            if not isinstance(name, str):
                raise ValueError(f"force group {group!r}: {name!r} is not a name")
            kind, _, bare = name.partition(":")
            if kind not in ("body", "subtree", "geom"):  # no prefix (or a name with a colon)
                kind, bare = "", name
            if kind == "geom" or (kind == "" and bare not in body_ids and bare in geom_ids):
                if bare not in geom_ids:
                    raise ValueError(
                        f"force group {group!r}: {bare!r} is no geom of the model; geoms: "
                        f"{sorted(geom_ids)}"
                    )
                member[geom_ids[bare], column] = True
                continue
            if bare not in body_ids:
                raise ValueError(
                    f"force group {group!r}: {bare!r} is no body of the model; bodies: "
                    f"{[b for b in bodies if b]} (geom:NAME names a geom)"
                )
            chosen = {body_ids[bare]}
            if kind == "subtree":
                for body in range(1, model.nbody):  # parents come before their children
                    if parents[body] in chosen:
                        chosen.add(body)
            hit = np.isin(np.asarray(model.geom_bodyid), sorted(chosen))
            if not hit.any():
                raise ValueError(f"force group {group!r}: body {bare!r} has no geoms")
            member[hit, column] = True
    return member


def settled(
    model: mujoco.MjModel, data: mujoco.MjData, scratch: mujoco.MjData | None = None
) -> mujoco.MjData:
    """A copy of ``data`` (into ``scratch``, a ``MjData`` of ``model``, when given) whose
    contacts and constraint forces are both of its current state: ``mj_forward`` without the
    sensors, on the copy, so the simulation it came from is not touched.

    Contact forces read straight after a dm_control step are not: its ``Physics.step`` ends with
    ``mj_step1`` (the new state's contacts and constraint rows) but leaves ``efc_force`` from the
    step before, so ``mj_contactForce`` mixes the two (measured on walker under random actions:
    31 of 341 contact normals negative, the summed force 19 % off at the median).
    """
    out = mujoco.MjData(model) if scratch is None else scratch
    mujoco.mj_copyData(out, model, data)
    mujoco.mj_forwardSkip(model, out, mujoco.mjtStage.mjSTAGE_NONE, 1)
    return out


def contact_forces(
    model: mujoco.MjModel, data: mujoco.MjData, component: str = "normal"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(geom1, geom2, force)`` of each of ``data``'s ``ncon`` contacts, ``force`` in N;
    ``data`` with its contacts and forces of one state (after ``mj_forward``; a dm_control
    env's data after a step: :func:`settled` of it).

    ``component``: ``normal``, the normal force (``mujoco.mj_contactForce``'s first entry), or
    ``total``, the norm of its 3 translational entries (normal and the two frictional). Contacts
    outside the constraint (in the margin gap, excluded) have no force.

    A loop over ``mj_contactForce``, which decodes the pyramidal or elliptic friction cone from
    ``data.efc_force``: at the few contacts of these envs it is cheaper than the same decoding
    in numpy (measured on walker, 4 contacts: 4.5 us against 14-21 us, numpy's per-call cost
    dominating), and it is MuJoCo's own reading.
    """
    if component not in COMPONENTS:
        raise ValueError(f"component must be one of {COMPONENTS}, got {component!r}")
    n = data.ncon
    force = np.zeros(n)
    if n == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, force
    reading = np.zeros(6)
    normal = component == "normal"
    for i in range(n):
        mujoco.mj_contactForce(model, data, i, reading)
        force[i] = reading[0] if normal else math.hypot(*reading[:3])
    geom = data.contact.geom
    return geom[:, 0], geom[:, 1], force


def geom_groups(member: np.ndarray) -> list[tuple[int, ...]]:
    """Per geom, the groups holding it (the rows of :func:`resolve_groups`' ``member``)."""
    return [tuple(np.flatnonzero(row).tolist()) for row in member]


def group_forces(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    member: np.ndarray,
    component: str = "normal",
    *,
    lookup: Sequence[tuple[int, ...]] | None = None,
) -> np.ndarray:
    """``[n_groups]`` N: each group's summed contact force (:func:`contact_forces`), ``member``
    from :func:`resolve_groups` (``lookup``: its :func:`geom_groups`, computed once by a caller
    that reads every step); a contact counts once per group holding either geom.

    A Python loop over the contacts, which reads ``mj_contactForce`` only for those touching a
    group: at walker's 1-2 contacts a step it costs 6-8 us where numpy's gather and matrix
    product over the contacts (``(member[geom1] | member[geom2]).T @ force``, the same sum)
    cost ~20 us (measured side by side)."""
    if component not in COMPONENTS:
        raise ValueError(f"component must be one of {COMPONENTS}, got {component!r}")
    of_geom = geom_groups(member) if lookup is None else lookup
    out = [0.0] * member.shape[1]
    if data.ncon == 0:
        return np.asarray(out)
    reading = np.zeros(6)
    normal = component == "normal"
    for i, (geom1, geom2) in enumerate(data.contact.geom.tolist()):
        first, second = of_geom[geom1], of_geom[geom2]
        if not (first or second):
            continue
        mujoco.mj_contactForce(model, data, i, reading)
        force = float(reading[0]) if normal else math.hypot(*reading[:3])
        for group in set(first).union(second) if first and second else first or second:
            out[group] += force
    return np.asarray(out)


def mujoco_reader(env: Any) -> Callable[[], tuple[mujoco.MjModel, mujoco.MjData]]:
    """``() -> (MjModel, MjData)`` of the simulator a TorchRL env steps: dm_control's
    (``DMControlEnv``: ``_env.physics.model.ptr``, read at each call: a composer env may recompile
    its physics on a reset), Gymnasium's (``GymEnv``: ``_env.unwrapped.model``), or that of an env
    holding ``model`` and ``data`` itself; a ``TypeError`` otherwise.

    Found once: an attribute TorchRL's wrapper lacks costs ~200 us to look up (it lists the
    module's names), the reader's plain attribute reads well under 1 us."""
    base = getattr(env, "base_env", env)
    inner = vars(base).get("_env")  # the wrapped library env, not through the wrapper's getattr
    if inner is not None and hasattr(inner, "physics") and hasattr(inner.physics, "model"):
        return lambda: (inner.physics.model.ptr, inner.physics.data.ptr)
    for holder in (inner, getattr(inner, "unwrapped", None), base):
        model = vars(holder).get("model") if hasattr(holder, "__dict__") else None
        data = vars(holder).get("data") if hasattr(holder, "__dict__") else None
        if isinstance(model, mujoco.MjModel) and isinstance(data, mujoco.MjData):
            return lambda holder=holder: (holder.model, holder.data)
    raise TypeError(
        f"{type(base).__name__} steps no MuJoCo model that the contacts adapter can read (a "
        "dm_control env's physics, a Gymnasium MuJoCo env's model and data)"
    )


def mujoco_handles(env: Any) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """``(MjModel, MjData)`` of the simulator a TorchRL env steps (:func:`mujoco_reader`)."""
    return mujoco_reader(env)()


class ContactForces(Transform):
    """Writes ``out_key`` ``[n_groups, 1]``: each group's summed contact force in N, after the
    reset and after each step.

    The normal force by default: it is what a MuJoCo touch sensor reports (the sum of the normal
    forces of the contacts in its zone), so an env read here is in the unit of the hand's and
    finger's touch sensors; friction adds a part bounded by ``mu`` times the normal that slides
    on without any strike (a foot scuffing the floor). ``component="total"`` reads the norm of
    the whole contact force instead. One simulator: an unbatched env (a batch of envs appends
    one to each).

    The reset writes the contacts the reset leaves (dm_control and Gymnasium run ``mj_forward``
    on a reset): cheetah starts resting on its feet, and zeros there would make its weight the
    first step's impact. ``reset_zeros=True`` writes zeros instead.

    Args:
        groups: group name -> body or geom names (:func:`resolve_groups`), in site order.
        out_key: where the force lands.
        component: ``normal`` or ``total`` (:func:`contact_forces`).
        reset_zeros: write zeros at a reset rather than the contacts it leaves.
        handles: ``() -> (MjModel, MjData)``; default: the parent env's
            (:func:`mujoco_reader`).
    """

    def __init__(
        self,
        groups: Mapping[str, Sequence[str]],
        *,
        out_key: str = FORCE,
        component: str = "normal",
        reset_zeros: bool = False,
        handles: Callable[[], tuple[mujoco.MjModel, mujoco.MjData]] | None = None,
    ) -> None:
        if component not in COMPONENTS:
            raise ValueError(f"ContactForces: component must be one of {COMPONENTS}")
        if not isinstance(groups, Mapping) or not groups:
            raise ValueError(f"ContactForces: groups must name at least one group, got {groups!r}")
        super().__init__(in_keys=[], out_keys=[out_key])
        self.groups = {str(k): tuple(v) for k, v in groups.items()}
        self.component, self.reset_zeros, self._handles = component, reset_zeros, handles
        self._model: mujoco.MjModel | None = None
        self._member: np.ndarray | None = None
        self._geom_groups: list[tuple[int, ...]] = []
        self._reader: Callable[[], tuple[mujoco.MjModel, mujoco.MjData]] | None = None
        self._scratch: mujoco.MjData | None = None  # the settled copy (:func:`settled`)

    @property
    def sites(self) -> list[str]:
        """The group names, in the order of ``out_key``'s first dim."""
        return list(self.groups)

    def set_container(self, container: Transform | EnvBase) -> None:
        self._reader = None  # appended to another env (a clone): its simulator, found again
        return super().set_container(container)

    def __getstate__(self) -> dict:
        state = super().__getstate__() if hasattr(super(), "__getstate__") else self.__dict__
        return {
            **state, "_reader": None, "_model": None, "_member": None, "_geom_groups": [],
            "_scratch": None,
        }  # fmt: skip

    def handles(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        """``(MjModel, MjData)`` of the env this transform reads."""
        if self._handles is not None:
            return self._handles()
        if self._reader is None:  # TorchRL builds ``parent`` anew on each access: found once
            parent = self.parent
            if parent is None:
                raise RuntimeError("ContactForces reads its env's simulator: append it to an env")
            self._reader = mujoco_reader(parent.base_env)
        return self._reader()

    def bind(self) -> ContactForces:
        """Resolve the group names against the env's model now (a one-line ``ValueError`` for
        an unknown name) rather than at the first reset."""
        self._membership(self.handles()[0])
        return self

    def _membership(self, model: mujoco.MjModel) -> np.ndarray:
        if model is not self._model:  # a new (recompiled) model: resolve the names again
            self._member, self._model = resolve_groups(model, self.groups), model
            self._geom_groups = geom_groups(self._member)
            self._scratch = mujoco.MjData(model)
        return self._member

    def read(self) -> torch.Tensor:
        """The force now, ``[n_groups, 1]`` float32 N: of the contacts and constraint forces of
        the simulator's current state (:func:`settled`)."""
        model, data = self.handles()
        member = self._membership(model)
        data = settled(model, data, self._scratch)
        force = group_forces(model, data, member, self.component, lookup=self._geom_groups)
        return torch.as_tensor(force, dtype=torch.float32).unsqueeze(-1)

    def _write(self, tensordict: TensorDictBase, force: torch.Tensor) -> TensorDictBase:
        tensordict.set(self.out_keys[0], force.to(tensordict.device or "cpu"))
        return tensordict

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        return self._write(next_tensordict, self.read())

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        if self.reset_zeros:
            return self._write(tensordict_reset, torch.zeros(len(self.groups), 1))
        return self._write(tensordict_reset, self.read())

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        return next_tensordict  # the force comes from the simulator, not from an entry

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        if observation_spec.shape:
            raise ValueError(
                f"ContactForces reads one simulator: append it to an unbatched env (batch "
                f"{tuple(observation_spec.shape)}), e.g. inside each env of a SerialEnv"
            )
        shape = (len(self.groups), 1)
        observation_spec[self.out_keys[0]] = Unbounded(
            shape, dtype=torch.float32, device=observation_spec.device
        )
        return observation_spec
