"""Hostile sweep files and ``--set`` items (issues 23 and 32): keys must be config fields, values
cannot leave ``--out``, no point reaches a Ray cluster, every point is validated before any runs,
and an interrupted point resumes."""

from __future__ import annotations

import re

import pytest

from gentlerl.apps.sweep_files import load_sweep
from gentlerl.apps.sweeps import main as sweep
from tests.helpers import files_under, sweep_file


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("+hydra.callbacks.a._target_", "numpy.savetxt"),
        ("hydra.run.dir", "x"),
        ("_target_", "builtins.open"),
        ("++seed", 1),
        ("+foo", 1),
        ("not_a_field", 1),
        ("network", 1),
        ("env.kwargs", 1),
        ("run_dir", "x"),
    ],
)
def test_sweep_keys_must_be_config_fields(tmp_path, key, value, capsys):
    path = sweep_file(tmp_path, f"parameters:\n  '{key}': {{values: [{value}]}}\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as err:
        sweep([path, "--out", str(out)])
    message = str(err.value.code)
    assert repr(key) in message and "\n" not in message
    assert not out.exists()


def test_a_sweep_callback_payload_writes_nothing(tmp_path):
    target = tmp_path / "pwned.txt"
    body = (
        "parameters:\n  seed: {values: [0]}\n"
        f"  +hydra.callbacks.a._target_: {{value: numpy.savetxt}}\n"
        f"  +hydra.callbacks.a._args_: {{value: ['{target}', [1, 2]]}}\n"
    )
    with pytest.raises(SystemExit, match="hydra"):
        sweep([sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert not target.exists()


@pytest.mark.parametrize(
    "value",
    ["r/../../../../x", "..", "a b", "${oc.env:HOME}", "r,x", "x=y", "'q'", "/abs"],
)
def test_sweep_values_cannot_leave_out(tmp_path, value):
    path = sweep_file(tmp_path, f"parameters:\n  variant: {{values: [{value!r}]}}\n")
    before = files_under(tmp_path)
    with pytest.raises(SystemExit, match="string value may hold only"):
        sweep([path, "--out", str(tmp_path / "out"), "--dry-run"])
    assert files_under(tmp_path) == before


@pytest.mark.parametrize(
    ("body", "match"),
    [
        (f"parameters: {{variant: {{values: [{'r' * 300}]}}}}\n", "longer than 255 bytes"),
        ("", "expected a mapping"),
        ("- a\n- b\n", "expected a mapping"),
        ("parameters: [1, 2]\n", "must be a mapping"),
        ("parameters: {seed: {values: []}}\n", "needs `values:`"),
        ("parameters: {seed: 3}\n", "needs `values:`"),
        ("parameters: {seed: {values: [[[1]]]}}\n", "nested lists"),
        ("parameters: {seed: {values: [{a: 1}]}}\n", "expected a number"),
        ("parameters: {seed: [\n", "not valid YAML"),
        # YAML 1.1's boolean words are words, and a boolean field takes true or false only
        ("parameters: {logging.progress: {values: [yes]}}\n", "logging.progress=yes must be"),
        ("parameters: {learner.compile: {value: off}}\n", "learner.compile=off must be true"),
        ("parameters: {learner.compile: {values: [true, 1]}}\n", "learner.compile=1 must be"),
        ("parameters: {variant: {values: [on]}}\n", "variant='on' is not one of"),
    ],
)
def test_malformed_sweep_files_are_one_line_refusals(tmp_path, body, match):
    with pytest.raises(SystemExit, match=match) as err:
        sweep([sweep_file(tmp_path, body), "--out", str(tmp_path / "out")])
    assert "\n" not in str(err.value.code)


def test_missing_sweep_file_and_bad_set_are_refused(tmp_path):
    with pytest.raises(SystemExit, match="No such file"):
        sweep([str(tmp_path / "none.yaml"), "--out", str(tmp_path)])
    good = sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    for item in ("hydra.job.chdir=true", "+hydra.callbacks.a._target_=os.system", "seed"):
        with pytest.raises(SystemExit, match="--set"):
            sweep([good, "--out", str(tmp_path / "o"), "--set", item, "--dry-run"])
    assert sweep([good, "--out", str(tmp_path / "o"), "--dry-run", "--set",
                  "+env.kwargs.regime=easy"]) == 0  # fmt: skip


def test_a_point_interrupted_before_its_first_checkpoint_resumes(tmp_path):
    from gentlerl.apps.sweeps import main as sweep
    from tests.apps.test_sweeps import TINY

    path = sweep_file(tmp_path, "parameters:\n  variant: {values: [r]}\n  seed: {values: [0]}\n")
    run = tmp_path / "out" / "evil" / "variant-r_seed-0"
    (run / "logs" / "scalars").mkdir(parents=True)  # what a point killed early leaves
    (run / "config.yaml").write_text("task: touch\n")
    args = [path, "--out", str(tmp_path / "out"), *sum((["--set", o] for o in TINY), [])]
    assert sweep(args) == 0
    assert (run / "DONE").exists() and (run / "checkpoint.pt").exists()


@pytest.mark.parametrize(
    ("parameters", "match"),
    [
        ("seed: {values: [0, -1]}", r"grid point seed--1: seed=-1 must be in \[0, 2147483647\]"),
        ("seed: {values: [4294967296]}", r"seed=4294967296 must be in \[0, 2147483647\]"),
        ("variant: {values: [bogus]}", "variant='bogus' is not one of"),
        ("gentleness.lam_prime: {values: [[2]]}", "gentleness.lam_prime=.* must have 2 values"),
    ],
)
def test_every_sweep_point_is_validated_before_any_runs(tmp_path, parameters, match):
    path = sweep_file(tmp_path, f"parameters:\n  {parameters}\n")
    with pytest.raises(SystemExit, match=match) as err:
        sweep([path, "--out", str(tmp_path / "out")])
    assert "\n" not in str(err.value.code) and not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("parameters", "allowed"),
    [
        ("collector.kind: {value: ray}\n  collector.ray_address: {value: evil.example:6379}", None),
        ("collector.ray_address: {value: evil.example:6379}", "applies to collector.kind=ray only"),
        ("collector.kind: {values: [single, ray]}", None),
    ],
)
def test_a_sweep_file_cannot_send_its_runs_to_a_ray_cluster(tmp_path, parameters, allowed, capsys):
    path = sweep_file(tmp_path, f"parameters:\n  {parameters}\n")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as err:
        sweep([path, "--out", str(out), "--dry-run"])
    message = str(err.value.code)
    assert "a sweep does not choose where its runs execute" in message and "\n" not in message
    assert "--allow-ray-collector" in message and "collector." in message
    assert "gentlerl.apps.train" not in capsys.readouterr().out  # nothing planned
    assert not out.exists()
    # the command line may allow it: then the point is planned (once its config is valid)
    allow = [path, "--out", str(out), "--dry-run", "--allow-ray-collector"]
    if allowed is None:
        assert sweep(allow) == 0
    else:
        with pytest.raises(SystemExit, match=allowed):
            sweep(allow)


@pytest.mark.parametrize(
    ("item", "match"),
    [
        ("logging.wandb_project=${oc.env:HOME}", "string value may hold only"),
        ("+env.kwargs.regime=${oc.env:HOME}", "string value may hold only"),
        ("collector.kind=ray", "a sweep does not choose where its runs execute"),
        ("collector.ray_address=evil.example:6379", "a sweep does not choose where"),
        ("seed=[1", "not a plain number, name or list"),
        ("seed={a: 1}", "expected a number, a name or a list"),
        ("learner.compile=yes", "learner.compile=yes must be true or false"),
        ("collector.overlap=on", "collector.overlap=on must be true or false"),
        ("collector.overlap=1", "collector.overlap=1 must be true or false"),
    ],
)
def test_set_follows_the_sweep_files_rules(tmp_path, item, match):
    good = sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    with pytest.raises(SystemExit, match=match) as err:
        sweep([good, "--out", str(tmp_path / "o"), "--set", item, "--dry-run"])
    assert f"--set {item!r}" in str(err.value.code) and "\n" not in str(err.value.code)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--backend", "ray", "--cpus-per-run", "0"], "--cpus-per-run=0.0 must be > 0"),
        (["--backend", "ray", "--address", "6379"], "--address '6379': '6379' is not a host"),
        (["--workers", "0"], "--workers=0 must be >= 1"),
    ],
)
def test_sweep_options_are_checked_before_anything_runs(tmp_path, args, message):
    good = sweep_file(tmp_path, "parameters: {seed: {values: [0]}}\n")
    with pytest.raises(SystemExit, match=re.escape(message)):
        sweep([good, "--out", str(tmp_path / "o"), "--dry-run", *args])
    assert not (tmp_path / "o").exists()


def test_a_word_yaml_1_1_reads_as_a_boolean_stays_a_word_for_a_string_field(tmp_path):
    path = sweep_file(tmp_path, "parameters: {logging.wandb_project: {values: [on, no]}}\n")
    assert load_sweep(path) == {"logging.wandb_project": ["on", "no"]}
