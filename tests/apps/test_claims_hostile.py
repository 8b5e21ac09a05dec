"""``gentlerl claims`` refuses a bad or missing final-evaluation file in one line."""

from __future__ import annotations

import pytest

from tests.helpers import minimal_run


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ('{"policy": "x/checkpoint.pt"}\n', "lacks 'success_rate'"),
        ("not json\n", "is not a JSON object"),
        ("[1, 2]\n", "is not a JSON object"),
        (
            '{"policy": "x/checkpoint.pt", "success_rate": 7}\n',
            r"success_rate=7.0 is not in \[0, 1\]",
        ),
    ],
)
def test_claims_refuses_a_bad_final_eval_file(tmp_path, content, match):
    from gentlerl.apps.claims import main as claims

    evals = tmp_path / "evals" / "sweep"
    evals.mkdir(parents=True)
    (evals / "final_eval.jsonl").write_text(content)
    minimal_run(tmp_path / "runs")
    with pytest.raises(ValueError, match=f"final_eval.jsonl:1.*{match}"):
        claims([str(tmp_path / "runs"), "--final-evals", str(tmp_path / "evals")])


def test_claims_refuses_a_missing_final_evals_folder(tmp_path):
    from gentlerl.apps.claims import main as claims

    minimal_run(tmp_path / "runs")
    for folder in (tmp_path / "nonexistent", tmp_path / "runs"):
        with pytest.raises(FileNotFoundError, match="--final-evals"):
            claims([str(tmp_path / "runs"), "--final-evals", str(folder)])
