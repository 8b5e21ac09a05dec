"""What left ``gentlerl.analysis`` in 0.2.0 (analysis.grid_tables, analysis.method3, the SAC grid's
and GentleBench's verdicts of analysis.criteria) is refused on import in one line naming where it
went."""

import importlib

import pytest


@pytest.mark.parametrize(
    ("module", "script"),
    [
        ("gentlerl.analysis.grid_tables", "experiments/sac_grid/table.py"),
        ("gentlerl.analysis.grid_tables", "experiments/gentlebench/table.py"),
        ("gentlerl.analysis.method3", "experiments/method3/table.py"),
    ],
)
def test_a_moved_module_names_its_script(module, script):
    with pytest.raises(ImportError, match=f"{module} moved out of the library in 0.2.0") as err:
        importlib.import_module(module)
    assert script in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("name", "where"),
    [
        ("sac_verdict", "experiments/sac_grid/criteria.py"),
        ("gentlebench_verdict", "experiments/gentlebench/criteria.py"),
        ("GENTLEBENCH_R_LEARNS", "experiments/gentlebench/criteria.py"),
    ],
)
def test_a_moved_criterion_names_its_file(name, where):
    with pytest.raises(ImportError, match=f"criteria.{name} moved out .* in {where}"):
        exec(f"from gentlerl.analysis.criteria import {name}")


def test_other_missing_names_are_still_attribute_errors():
    from gentlerl.analysis import criteria

    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        criteria.nope  # noqa: B018
    assert criteria.judge and not hasattr(criteria, "nope")
