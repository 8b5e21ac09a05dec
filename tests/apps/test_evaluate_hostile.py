"""``gentlerl evaluate`` checks its output, seed and the policy's sizes before any episode."""

from __future__ import annotations

import pytest

from tests.helpers import policy_file


def test_evaluate_checks_its_csv_and_seed_before_any_episode(tmp_path):
    from gentlerl.apps.evaluate import evaluate_policy

    missing = tmp_path / "no_policy.pt"  # never reached: the output is checked first
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(IsADirectoryError, match="is a directory"):
        evaluate_policy(missing, 1, episodes_csv=tmp_path / "dir.csv")
    with pytest.raises(ValueError, match="must end in .csv"):
        evaluate_policy(missing, 1, episodes_csv=tmp_path / "out.txt")
    for seed in (-1, 2**32):
        with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*32\)"):
            evaluate_policy(missing, 1, seed=seed)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.csv"]


def test_a_policy_for_another_env_is_refused_naming_both_sizes(tmp_path):
    from gentlerl.apps.evaluate import evaluate_policy

    path = policy_file(tmp_path, [16], [16])  # obs_dim 10; the touch hand's observation: 63
    with pytest.raises(ValueError, match=r"policy.pt: its actor has obs_dim=10, but this env's "):
        evaluate_policy(path, 1)
