"""Golden losses: a fixed-seed toy-env run logs the same first 200 updates' losses as recorded.

The fixture ``tests/data/golden_losses.json`` was written by this file's ``record`` (run
``python -m tests.repo.test_golden``) before the training code was reorganised; a refactor that keeps
behaviour must reproduce it. Regenerate the fixture (and say why in the commit) only when the
behaviour is meant to change, or the torch build does.

Floating-point results depend on the CPU's code path (AVX-512, AVX2, plain; MKL's kernels pick
by CPU), so the comparison has two tiers, measured on 2026-12-02 against the fixture on one
AMD EPYC under ``ATEN_CPU_CAPABILITY`` ``avx512`` (its default), ``avx2`` and ``default``:

* the first :data:`EXACT_UPDATES` updates to float rounding (:data:`EXACT_REL`): every code path
  agreed to 3.1e-7 relative there, before rounding differences compound through the
  updates;
* all :data:`LOGGED` updates within :data:`LATE_REL` of each series' largest magnitude: the
  paths drift apart later, by at most 4.7e-5 relative (``model_penalty``, whose values cross
  zero: 2.5e-5 absolute on a series reaching 6.8), 140x inside the bound.

``test_a_one_percent_change_of_one_learning_rate_is_caught`` shows that a change of behaviour far
smaller than any refactor bug (one learning rate moved by 1 %) fails the comparison.
"""

import csv
import json
import re
import sys
from pathlib import Path

import pytest
import torch

from gentlerl.training import make_config, train
from tests.toy_env import ToyHandEnv

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "golden_losses.json"
#: 200 updates (utd 0.5 over the 400 frames after 200 random ones), 2-frame batches: one
#: update and one log row per batch.
LOGGED = 200
#: Every value the run depends on is spelled out, so later changes of defaults do not move it.
CONFIG = dict(
    seed=0,
    num_threads=1,
    collector=dict(
        total_frames=600, frames_per_batch=2, init_random_frames=200, kind="single", sigma=0.3
    ),
    replay=dict(
        batch_size=32, buffer_size=200_000, n_steps=5, prioritized=True, alpha=0.6, beta=0.4
    ),
    learner=dict(
        utd_ratio=0.5,
        lr_actor=1e-4,
        lr_critic=3e-4,
        gamma=0.99,
        target_update_period=100,
        policy_noise=0.0,
        episodic_intrinsic=False,
    ),
    network=dict(
        actor_hidden=(32, 32),
        critic_hidden=(32, 32),
        num_atoms=11,
        v_min=-10.0,
        v_max=10.0,
        bounded_support=True,  # the penalty head's support tops at 0
        dense_reward_bound=None,  # one shared [v_min, v_max] for every head
    ),
    gentleness=dict(
        lam=(2.0, 2.0),
        lam_prime=(2.0, 2.0),
        reward_delay=100,
        dynamics_target_period=20,
        penalty_target_period=10,
        ensemble_size=5,
        model_hidden=16,
        model_batch_size=16,
        model_buffer_size=100_000,
        lr_model=1e-3,
        surprise_scale=1.0,
        dynamics_surprise_scale=1.0,
        surprise_nll_floor=0.0,
        rescore_surprise=False,
        icm_eta=1.0,
    ),
    logging=dict(
        eval_every_frames=600,
        eval_episodes=1,
        log_every_updates=1,
        checkpoint_every_frames=600,
        wandb_mode="disabled",
        progress=False,
    ),
)
#: Updates compared to float rounding, and the relative tolerance there.
EXACT_UPDATES = 50
EXACT_REL = 1e-5
#: The bound on every update, relative to the largest magnitude of its series.
LATE_REL = 1e-3
#: The variants compared over all LOGGED updates by default (about 4 s each on the 2-core CPU).
#: ICM's 200 updates run on the slow path only: on the AMD EPYC of 2026-12-07 under its native
#: (AVX-512) code path its ``loss_actor`` leaves the recording by 2.8e-3 of the series' largest
#: magnitude at update 183 (above :data:`LATE_REL`; under ``avx2`` and ``default`` it stays
#: inside), while its first 50 updates agree to 2.0e-7 and its other series stay within 3.6e-5.
#: The default run checks all but that actor loss's late tier
#: (:func:`test_the_icm_variant_matches_but_for_its_late_actor_loss`).
#: On that code path the slow r+icm comparison is an expected failure (the drift above, measured
#: again on 2026-12-08: ``loss_actor[183]`` -1.5659 against the recorded -1.5704); elsewhere it
#: must pass.
_ICM_DRIFTS = torch.backends.cpu.get_cpu_capability() == "AVX512"
VARIANTS = (
    "r+rf+rsp",
    "r+rf+rs",
    pytest.param(
        "r+icm",
        marks=[
            pytest.mark.slow,
            pytest.mark.xfail(
                _ICM_DRIFTS,
                reason="AVX-512: r+icm's late actor loss drifts 2.8e-3 of its series (measured)",
                strict=True,
            ),
        ],
    ),
)


def golden_run(run_dir: Path, variant: str, config: dict | None = None) -> dict[str, list[float]]:
    """Every ``train/loss_*`` and ``train/model_*`` scalar of one update per log row."""
    cfg = make_config(**(config or CONFIG), variant=variant, run_dir=str(run_dir))
    train(cfg, ToyHandEnv)
    out = {}
    for path in sorted((run_dir / "logs" / "scalars" / "train").glob("*.csv")):
        if path.stem.startswith(("loss_", "model_")):
            out[path.stem] = [float(v) for _, v in csv.reader(path.open())]
    return out


def record(root: Path) -> None:
    names = ("r+rf+rsp", "r+rf+rs", "r+icm")
    data = {v: golden_run(root / v.replace("+", "_"), v) for v in names}
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(json.dumps(data, indent=1) + "\n")


def mismatches(got: dict[str, list[float]], expected: dict[str, list[float]]) -> list[str]:
    """Where ``got`` leaves the recording by more than the module docstring's two tiers allow."""
    if sorted(got) != sorted(expected):
        return [f"scalars {sorted(got)} != recorded {sorted(expected)}"]
    problems = []
    for name, values in expected.items():
        ours = got[name]
        if len(values) != LOGGED or len(ours) != LOGGED:
            problems.append(f"{name}: {len(ours)} rows, recorded {len(values)}, want {LOGGED}")
            continue
        late_abs = LATE_REL * max(abs(v) for v in values)
        for i, (a, b) in enumerate(zip(ours, values, strict=True)):
            exact = i < EXACT_UPDATES and abs(a - b) > EXACT_REL * abs(b) + 1e-7
            if exact or abs(a - b) > late_abs:
                problems.append(f"{name}[{i}] = {a!r}, recorded {b!r}")
                break
    return problems


@pytest.mark.parametrize("variant", VARIANTS)
def test_first_200_logged_losses_match_the_recorded_run(tmp_path, variant):
    expected = json.loads(FIXTURE.read_text())[variant]
    assert mismatches(golden_run(tmp_path, variant), expected) == []


def _first_index(problem: str) -> int:
    """The update a :func:`mismatches` line names (``"name[i] = ..."`` -> ``i``); -1 for a
    line that names none (other scalars, or another number of rows)."""
    found = re.match(r"\w+\[(\d+)\] = ", problem)
    return int(found.group(1)) if found else -1


def test_the_icm_variant_matches_but_for_its_late_actor_loss(tmp_path):
    """Both tiers on every series of r+icm but ``loss_actor``'s late one (the slow test's): the
    ICM reward switches on after ``reward_delay`` = 100 updates, so its critic's loss
    (``loss_value_icm_reward``, late drift 3.6e-5 here) must be read past them."""
    expected = json.loads(FIXTURE.read_text())["r+icm"]
    problems = mismatches(golden_run(tmp_path, "r+icm"), expected)
    late_actor = [
        p for p in problems if p.startswith("loss_actor[") and _first_index(p) >= EXACT_UPDATES
    ]
    assert [p for p in problems if p not in late_actor] == []


def test_a_one_percent_change_of_one_learning_rate_is_caught(tmp_path):
    expected = json.loads(FIXTURE.read_text())["r+rf+rsp"]
    config = {**CONFIG, "gentleness": {**CONFIG["gentleness"], "lr_model": 1.01e-3}}
    problems = mismatches(golden_run(tmp_path, "r+rf+rsp", config), expected)
    where = {p.split("[")[0]: _first_index(p) for p in problems}
    assert where["model_penalty"] < EXACT_UPDATES  # the exact tier sees it at once


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        record(Path(tmp))
    sys.exit(0)
