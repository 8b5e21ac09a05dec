"""The pre-registered criteria as code: verdicts from synthetic grids with known numbers."""

import json
import math

import pytest
import yaml

from gentlerl.analysis.claims import load_final_evals
from gentlerl.analysis.criteria import first_success_frame, judge, touch_stats
from gentlerl.analysis.runs import find_runs, load_run
from gentlerl.apps.claims import main


def _run(root, task, variant, seed, impacts, success, final_eval=()):
    """A run dir: intrinsic rewards on at frame 1000; ``impacts`` logged every 200 frames from
    1200 on (so all after the switch); evaluations at 1000, 2000, 3000; ``final_eval`` rows
    ``(success, max_impact)`` of the last evaluation."""
    run = root / task / f"{variant}_seed{seed}"
    scalars = run / "logs" / "scalars"
    for sub in ("eval", "episode", "train"):
        (scalars / sub).mkdir(parents=True)
    config = {"task": task, "variant": variant, "seed": seed, "collector": {}}
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    (scalars / "train" / "intrinsic_on.csv").write_text("800,0\n1000,1\n")
    (scalars / "episode" / "max_impact.csv").write_text(
        "400,99\n" + "".join(f"{1200 + 200 * i},{m}\n" for i, m in enumerate(impacts))
    )
    (scalars / "eval" / "success_rate.csv").write_text(
        "".join(f"{f},{s}\n" for f, s in zip((1000, 2000, 3000), success, strict=True))
    )
    rows = "".join(f"3000,{i},{s},0,{m},{s}\n" for i, (s, m) in enumerate(final_eval))
    (run / "eval_episodes.csv").write_text(
        "frames,episode,success,broken,max_impact,return\n" + rows
    )
    return run


def _paper_like_grid(root):
    """A grid where every claim holds as the paper states it."""
    for seed in (0, 1):
        _run(root, "explore", "rs", seed, [0, 6, 8, 12, 4], (0, 0, 0))
        _run(root, "explore", "rf+rs", seed, [0, 0, 0, 2, 3], (0, 0, 0))
        _run(root, "explore", "rf+rsp", seed, [0, 1, 2, 1.5, 2], (0, 0, 0))
        _run(root, "touch", "r", seed, [3, 3], (0, 1, 1), [(1, 4.0), (1, 4.0)])
        _run(root, "touch", "r+rf", seed, [0, 0, 0, 1], (0, 0, 0))
        _run(root, "touch", "r+rf+rs", seed, [0, 0, 0, 1], (0, 0, 0))
        _run(root, "touch", "r+rf+rsp", seed, [1, 1, 1, 0], (0, 0.8, 1), [(1, 1.0), (1, 2.0)])
        _run(root, "touch", "r+icm", seed, [3], (0, 0, 0.2))
        _run(root, "fragile", "r", seed, [4, 0], (0, 0, 0.2))
        _run(root, "fragile", "r+rf+rsp", seed, [1, 1], (0, 1, 0.9))
        _run(root, "fragile", "r+icm", seed, [4], (0, 0, 0))


def _groups(root):
    groups = {}
    for run in find_runs([root]):
        groups.setdefault((run.config["task"], run.config["variant"]), []).append(run)
    return groups


def test_touch_stats_use_the_rollouts_after_the_switch(tmp_path):
    run = load_run(_run(tmp_path, "explore", "rs", 0, [0, 6, 8, 12, 4], (0, 0, 0)))
    stats = touch_stats([run])  # the 99 N rollout at frame 400 is before the switch
    assert stats["rollouts"] == 5
    assert stats["touch"] == 0.8
    assert stats["median"] == 7.0
    assert stats["in_5_15"] == 0.75
    assert stats["below_5"] == 0.25


def test_first_success_frame_is_inf_when_a_seed_never_gets_there(tmp_path):
    a = load_run(_run(tmp_path, "touch", "r", 0, [1], (0, 0.8, 1)))
    b = load_run(_run(tmp_path, "touch", "r", 1, [1], (0, 0, 0.5)))
    assert first_success_frame([a]) == 2000
    assert math.isinf(first_success_frame([a, b]))


def test_a_grid_that_behaves_like_the_paper_reproduces_every_claim(tmp_path):
    _paper_like_grid(tmp_path)
    verdicts = judge(_groups(tmp_path))
    assert [v.claim for v in verdicts] == [1, 2, 3, 4, 5, 6]
    assert [v.verdict for v in verdicts] == ["reproduced"] * 6, [v.numbers for v in verdicts]


def test_weaker_evidence_gives_partly_and_not_reproduced(tmp_path):
    _paper_like_grid(tmp_path)
    groups = _groups(tmp_path)
    # Final successes from the 20-episode evaluations override the in-loop ones.
    evals = {str(r.path.resolve()): 0.4 for r in groups[("touch", "r+rf")]}
    evals |= {str(r.path.resolve()): 0.9 for r in groups[("fragile", "r")]}
    evals |= {str(r.path.resolve()): 1.0 for r in groups[("touch", "r+icm")]}
    by_claim = {v.claim: v for v in judge(groups, evals)}
    assert by_claim[4].verdict == "partly"  # 0.4 <= 0.5 but > 0.2
    assert "`r+rf` 0.40" in by_claim[4].numbers
    assert by_claim[6].verdict == "not reproduced"  # fragile: r 0.9, r+rf+rsp 0.9
    del groups[("explore", "rs")]
    assert {v.claim: v.verdict for v in judge(groups)}[1] == "no data"


def test_cli_reads_final_evals_and_writes_the_table(tmp_path, capsys):
    _paper_like_grid(tmp_path / "runs")
    evals = tmp_path / "figs" / "fig4_fragile"
    evals.mkdir(parents=True)
    policy = tmp_path / "runs" / "fragile" / "r+rf+rsp_seed0" / "checkpoint.pt"
    (evals / "final_eval.jsonl").write_text(
        json.dumps({"policy": str(policy), "success_rate": 0.3})
    )
    assert load_final_evals(tmp_path / "figs") == {str(policy.parent.resolve()): 0.3}
    out = tmp_path / "claims.md"
    main([str(tmp_path / "runs"), "--final-evals", str(tmp_path / "figs"), "--markdown", str(out)])
    printed = capsys.readouterr().out
    assert printed == out.read_text()
    # seed 0 from final_eval.jsonl (0.3), seed 1 from its last evaluation (0.9)
    assert "| 6 | **partly** | fragile final success `r` 0.20, `r+rf+rsp` 0.60" in printed


def test_cli_compares_rows_on_the_seeds_they_share(tmp_path, capsys):
    _paper_like_grid(tmp_path / "full")
    _paper_like_grid(tmp_path / "ablated")
    # seed 2 of `r+rf` in the ablated row learns touch: claim 4 drops (mean 0.33) on all seeds only
    _run(tmp_path / "ablated", "touch", "r+rf", 2, [0, 4, 4], (0, 1, 1))
    rows = [f"full={tmp_path / 'full'}", f"ablated={tmp_path / 'ablated'}"]
    main(rows)
    printed = capsys.readouterr().out
    assert printed.startswith("| # | full | ablated |\n| --- | --- | --- |\n")
    assert "| 4 | reproduced | partly |" in printed
    assert "### ablated" in printed and "23 runs under" in printed
    main([*rows, "--seeds", "0,1"])
    printed = capsys.readouterr().out
    assert "| 4 | reproduced | reproduced |" in printed
    assert "22 runs (seeds 0,1) under" in printed


def test_cli_rejects_bad_seeds_and_empty_selections(tmp_path, capsys):
    _paper_like_grid(tmp_path)
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--seeds", "zero"])
    assert "--seeds takes integers like 0,1; got 'zero'" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError, match=r"no runs of seeds \[7\]"):
        main([str(tmp_path), "--seeds", "7"])
