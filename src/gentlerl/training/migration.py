"""Configs saved by earlier versions, as today's :func:`~gentlerl.training.config.make_config`
takes them: the one place that knows how the settings changed (fields grouped, renamed, added
with a default that changed the method, hand keywords renamed), so that an old checkpoint
resumes and evaluates as it trained."""

from __future__ import annotations

import dataclasses
from typing import Any

from gentlerl.config import GROUPS

#: Flat field names of configs saved before the grouping whose grouped name is not the same name.
_RENAMED = {"collector": ("collector", "kind"), "env_kwargs": ("env", "kwargs")}


def group_flat_config(values: dict[str, Any]) -> dict[str, Any]:
    """A config saved before the fields were grouped (older checkpoints), as :func:`make_config`
    takes it: each flat field moved into the group that holds that name now.

    ``penalty_v_max`` (the penalty head's top, null for none) becomes ``network.bounded_support``
    (null: false, else true). A name no group holds stays at the top level, where
    :func:`make_config` reports it. A field added since the config was saved and listed in
    :data:`_BEFORE` gets the value that reproduces what that run trained (not today's default), and
    a hand task keyword renamed since (``env.kwargs.calibration``) gets its new name
    (:data:`~gentlerl.envs.task_names.RENAMED_KWARGS`).
    """
    if all(isinstance(values.get(group), dict) for group in GROUPS):
        return _with_earlier_behaviour(values)
    owner = {f.name: (g, f.name) for g, cls in GROUPS.items() for f in dataclasses.fields(cls)}
    owner.update(_RENAMED)
    grouped: dict[str, Any] = {}
    for name, value in values.items():
        if name == "penalty_v_max":
            name, value = "bounded_support", value is not None
        if name in owner:
            group, field = owner[name]
            grouped.setdefault(group, {})[field] = value
        else:
            grouped[name] = value
    return _with_earlier_behaviour(grouped)


#: Fields whose default changed the method, with the value that configs saved before them ran.
_BEFORE = {
    ("network", "dense_reward_bound"): None,  # one shared [v_min, v_max] for every head
    ("gentleness", "rescore_surprise"): False,  # r^sp stored at collection
    ("gentleness", "dynamics_surprise_scale"): 1.0,  # r^s as eq. 6 writes it
}


#: Grouped fields renamed since (old name -> new name, in the same group).
_RENAMED_FIELDS = {("gentleness", "recompute_surprise"): "rescore_surprise"}


def _with_earlier_behaviour(grouped: dict[str, Any]) -> dict[str, Any]:
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in grouped.items()}
    for (group, old), new in _RENAMED_FIELDS.items():
        if isinstance(out.get(group), dict) and old in out[group]:
            out[group].setdefault(new, out[group].pop(old))
    for (group, name), value in _BEFORE.items():
        if isinstance(out.get(group), dict):  # a group the saved config has, without the field
            out[group].setdefault(name, value)
    env = out.get("env")
    if isinstance(env, dict) and env.get("name") is None and isinstance(env.get("kwargs"), dict):
        from gentlerl.envs.task_names import RENAMED_KWARGS  # the hand's keywords renamed since

        env["kwargs"] = {RENAMED_KWARGS.get(k, k): v for k, v in env["kwargs"].items()}
    return out
