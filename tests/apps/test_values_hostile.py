"""One reading of a value for ``gentlerl train``, ``--set`` (seeds, sweep, suite), sweep files and
suite files (issue 63): YAML 1.2 core numbers everywhere, so ``010`` is 10, ``1e-3`` a float,
``1:04`` and ``1_000`` refused, and ``!!bool 2`` a one-line error, never a ``KeyError``."""

from __future__ import annotations

import pytest

from gentlerl.apps.seeds import group_configs
from gentlerl.apps.suite_files import load_suite
from gentlerl.apps.sweep_files import load_sweep, parse_set


def _train(item: str):
    """The config ``gentlerl train ITEM`` trains (hydra's composition, then the checks), or its
    one-line refusal as a ``ValueError``."""
    from hydra import compose, initialize
    from hydra.core.global_hydra import GlobalHydra

    from gentlerl.apps.overrides import hydra_error_line, override_problems
    from gentlerl.apps.train import config_from_hydra, register_configs

    if problems := override_problems([item]):
        raise ValueError(problems[0])
    register_configs()
    GlobalHydra.instance().clear()
    with initialize(version_base="1.3", config_path=None):
        try:
            return config_from_hydra(compose("gentlerl_train", overrides=[item]))
        except (ValueError, TypeError):
            raise
        except Exception as err:  # noqa: BLE001 - hydra's own errors, as the command words them
            raise ValueError(hydra_error_line(err, [item])) from None


def _set(item: str):
    return group_configs([0], [item], "unused")[0]


def _sweep(item: str, tmp_path):
    """The value a sweep file's ``values: [TEXT]`` gives its key."""
    key, _, text = item.partition("=")
    path = tmp_path / "sweep.yaml"
    path.write_text(f"parameters:\n  {key}:\n    values: [{text}]\n")
    (value,) = load_sweep(path)[key]
    return value


def _suite(item: str, tmp_path):
    path = tmp_path / "suite.yaml"
    path.write_text(
        f"suite: s\nseeds: [0]\nset: ['{item}']\ntasks:\n  t: [task=touch]\nvariants:\n  r: [variant=r]\n"
    )
    (cell,) = load_suite(path).cells
    return group_configs([0], cell.items, "unused")[0]


def _field(cfg, key):
    group, name = key.split(".")
    return getattr(getattr(cfg, group), name)


@pytest.mark.parametrize(
    ("item", "expected"),
    [
        ("replay.batch_size=010", 10),  # YAML 1.1 read 8 in --set, sweep and suite files
        ("learner.lr_actor=1e-3", 0.001),  # YAML 1.1 read the text "1e-3": refused there
        ("learner.lr_critic=+5e-4", 5e-4),
        ("replay.batch_size=64", 64),
    ],
)
def test_a_number_is_read_the_same_by_every_command(tmp_path, item, expected):
    key = item.partition("=")[0]
    assert _field(_train(item), key) == expected
    assert _field(_set(item), key) == expected
    assert _field(_suite(item, tmp_path), key) == expected
    value = _sweep(item, tmp_path)
    assert value == expected and type(value) is type(expected)


@pytest.mark.parametrize(
    ("item", "fragment"),
    [
        ("replay.batch_size=1:04", "must be"),  # YAML 1.1: 64 (sexagesimal)
        ("replay.batch_size=1_000", "1_000"),  # hydra: 1000; YAML 1.2: a word
        ("replay.batch_size=0x10", "must be"),
    ],
)
def test_a_yaml_1_1_number_is_refused_by_every_command(tmp_path, item, fragment):
    for read in (_train, _set, lambda i: _suite(i, tmp_path)):
        with pytest.raises(ValueError, match=fragment) as err:
            read(item)
        assert "replay.batch_size" in str(err.value)  # the commands print it as one line


@pytest.mark.parametrize("text", ["!!bool 2", "!!int 1:04", "!!float abc"])
def test_an_explicit_tag_on_a_text_it_does_not_fit_is_one_line_not_a_key_error(tmp_path, text):
    with pytest.raises(ValueError, match="is not a plain number, name or list"):
        parse_set([f"learner.compile={text}"])
    path = tmp_path / "sweep.yaml"
    path.write_text(f"parameters:\n  learner.compile:\n    value: {text}\n")
    with pytest.raises(
        ValueError,
        match=r"not valid YAML \(.* is not (true or false|an integer|a number) \(YAML 1.2 core\)",
    ):
        load_sweep(path)


def test_scale_is_one_preset_not_a_list_on_every_command(tmp_path):
    """The finding: ``--set 'scale=[cpu]'`` raised "unhashable type: 'list'"; ``gentlerl train
    scale=[cpu]`` merged a list of presets."""
    with pytest.raises(ValueError, match=r"unknown scale \['cpu'\]; expected one of"):
        _set("scale=[cpu]")
    with pytest.raises(ValueError, match=r"scale=\[cpu\]: scale is one preset of"):
        _train("scale=[cpu]")
