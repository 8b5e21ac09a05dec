"""Deprecated names (gentlerl.deprecation, gentlerl.lazy's ``deprecated=``): each use warns once,
in one line naming the old name, the new one and the release that removes it, and forwards.

pyproject.toml ignores DeprecationWarning in the suite, so each test records warnings itself.
"""

import subprocess
import sys
import types
import warnings
from pathlib import Path

import pytest

from gentlerl.deprecation import REMOVED_IN, deprecation_message, moved_method
from gentlerl.lazy import lazy_exports

ROOT = Path(__file__).resolve().parents[1]


def _one_warning(action):
    """``action()``'s result and the one DeprecationWarning it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = action()
    deprecations = [w for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(deprecations) == 1, [str(w.message) for w in caught]
    return result, deprecations[0]


def test_the_message_is_one_line_naming_old_new_and_the_release():
    message = deprecation_message("gentlerl.agent.IntrinsicRewards", "gentlerl.rewards.X")
    assert message == (
        "gentlerl.agent.IntrinsicRewards is deprecated, use gentlerl.rewards.X; "
        "it will be removed in 0.3.0"
    )
    assert REMOVED_IN == "0.3.0" and "\n" not in message


@pytest.mark.parametrize(
    "name", ["IntrinsicRewards", "COMPONENTS", "VARIANTS", "Component", "Part", "reward_keys"]
)
def test_the_agent_packages_moved_names_warn_and_are_the_rewards_ones(name):
    import gentlerl.agent
    import gentlerl.rewards

    value, warning = _one_warning(lambda: getattr(gentlerl.agent, name))
    assert value is getattr(gentlerl.rewards, name)
    assert str(warning.message) == deprecation_message(
        f"gentlerl.agent.{name}", f"gentlerl.rewards.{name}"
    )
    assert warning.filename == __file__  # points at the code that used the old name
    assert name not in gentlerl.agent.__all__ and name not in dir(gentlerl.agent)


def test_from_import_of_a_moved_name_warns():
    def old_import():
        from gentlerl.agent import IntrinsicRewards

        return IntrinsicRewards

    from gentlerl.rewards import IntrinsicRewards

    value, warning = _one_warning(old_import)  # importlib's hasattr probe does not warn too
    assert value is IntrinsicRewards and warning.filename == __file__


def test_a_moved_name_warns_at_every_read_and_an_unknown_one_still_fails():
    package = types.ModuleType("gentlerl_fake")
    sys.modules["gentlerl_fake"] = package
    try:
        getattr_, _, all_ = lazy_exports(
            "gentlerl_fake", {"gentlerl.keys": ("TOUCH",)}, deprecated={"OLD": ("gentlerl", "keys")}
        )
        package.__getattr__ = getattr_
        import gentlerl.keys

        for _ in range(2):  # not cached in the package: the second read warns too
            assert _one_warning(lambda: package.OLD)[0] is gentlerl.keys
        assert all_ == ["TOUCH"]
        with pytest.raises(AttributeError, match="has no attribute 'NEW'"):
            package.NEW  # noqa: B018
    finally:
        del sys.modules["gentlerl_fake"]


def test_a_name_both_exported_and_deprecated_is_refused():
    with pytest.raises(ValueError, match=r"\['A'\] are both exported and deprecated"):
        lazy_exports("p", {"m": ("A",)}, deprecated={"A": ("n", "B")})


class _Owner:
    rewards = "the rewards"
    old_call = moved_method("old_call", "new_call")
    old_make = moved_method("old_make", "rewards", attribute=True)

    def new_call(self, x, *, y=0):
        return (x, y)


def test_a_moved_method_warns_and_forwards_its_arguments():
    owner = _Owner()
    result, warning = _one_warning(lambda: owner.old_call(1, y=2))
    assert result == (1, 2)
    assert str(warning.message) == deprecation_message("_Owner.old_call()", "_Owner.new_call()")
    assert _Owner.old_call.__name__ == "old_call" and REMOVED_IN in _Owner.old_call.__doc__


def test_a_make_method_that_became_an_attribute_returns_it():
    result, warning = _one_warning(_Owner().old_make)
    assert result == "the rewards"
    assert str(warning.message) == deprecation_message("_Owner.old_make()", "_Owner.rewards")
    with pytest.raises(TypeError, match="takes no arguments"):
        _Owner().old_make(1)


def test_the_moved_methods_of_intrinsic_rewards_and_agent_builder_forward():
    from gentlerl.agent import AgentBuilder
    from gentlerl.rewards import IntrinsicRewards

    rewards = IntrinsicRewards.__new__(IntrinsicRewards)
    rewards.rescore_transform = lambda reward_sum=None: ("rescore", reward_sum)
    assert _one_warning(lambda: rewards.sampling_transform("sum"))[0] == ("rescore", "sum")
    builder = AgentBuilder.__new__(AgentBuilder)
    builder.rewards = rewards
    assert _one_warning(builder.make_intrinsic_rewards)[0] is rewards


def test_recipes_train_py_warns_and_runs_gentlerl_train(tmp_path):
    env = {"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}

    def run(*args):
        return subprocess.run(
            [sys.executable, *args, "--help"], capture_output=True, text=True, env=env,
            cwd=tmp_path, timeout=120,
        )  # fmt: skip

    old, new = run(str(ROOT / "recipes" / "train.py")), run("-m", "gentlerl", "train")
    assert old.returncode == new.returncode == 0
    assert old.stdout == new.stdout and "gentlerl-train" in old.stdout
    expected = deprecation_message("python recipes/train.py", "gentlerl train")
    assert f"DeprecationWarning: {expected}" in old.stderr
    assert old.stderr.count("DeprecationWarning") == 1 and "Deprecation" not in new.stderr


def test_touch_calibration_warns_and_is_touch_sensor_map():
    import gentlerl.transforms
    from gentlerl.transforms import TouchSensorMap

    value, warning = _one_warning(lambda: gentlerl.transforms.TouchCalibration)
    assert value is TouchSensorMap
    assert str(warning.message) == deprecation_message(
        "gentlerl.transforms.TouchCalibration", "gentlerl.transforms.TouchSensorMap"
    )
    assert warning.filename == __file__
    assert "TouchCalibration" not in gentlerl.transforms.__all__

    def old_import():
        from gentlerl.transforms import TouchCalibration

        return TouchCalibration

    assert _one_warning(old_import)[0] is TouchSensorMap  # one warning, not the probe's too


@pytest.mark.parametrize("old", [False, True])
def test_gentleness_configs_recompute_surprise_warns_and_sets_rescore_surprise(old):
    import dataclasses

    from gentlerl.config import GentlenessConfig

    cfg, warning = _one_warning(lambda: GentlenessConfig(recompute_surprise=old))
    assert cfg.rescore_surprise is old
    assert str(warning.message) == deprecation_message(
        "GentlenessConfig(recompute_surprise=...)", "GentlenessConfig(rescore_surprise=...)"
    )
    assert warning.filename == __file__  # the line that passed the old keyword
    # not a field: a config, its copies and its saved form hold rescore_surprise only
    assert "recompute_surprise" not in {f.name for f in dataclasses.fields(cfg)}
    assert "recompute_surprise" not in dataclasses.asdict(cfg)
    assert dataclasses.replace(cfg, icm_eta=2.0).rescore_surprise is old
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert GentlenessConfig().rescore_surprise is True  # the new name alone: no warning
        assert GentlenessConfig(rescore_surprise=False).rescore_surprise is False
