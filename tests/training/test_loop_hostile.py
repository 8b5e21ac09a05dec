"""``train`` refuses before writing: a locked run directory, a resume with no checkpoint, an external
env's bad settings."""

from __future__ import annotations

import pytest

from tests.helpers import files_under


def test_train_refuses_a_locked_run_dir_before_writing(tmp_path):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train
    from gentlerl.training.run_lock import RunLock, RunLockedError

    run_dir = tmp_path / "run"
    with RunLock(run_dir):
        before = files_under(tmp_path)
        with pytest.raises(RunLockedError, match="is in use by"):
            train(make_config(run_dir=str(run_dir), resume="auto"))
        assert files_under(tmp_path) == before


def test_a_refused_run_leaves_no_empty_run_dir(tmp_path):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    run_dir = tmp_path / "run"
    with pytest.raises(ValueError, match="resume=true but there is no checkpoint"):
        train(make_config(run_dir=str(run_dir), resume=True))
    assert not run_dir.exists()


@pytest.mark.parametrize(
    ("env", "match"),
    [
        ({"kwargs": {"bogus": 1}}, "env.kwargs.bogus=1 is not a keyword of the env: cannot build"),
        ({"kwargs": {"frame_skip": 0}}, r"env.kwargs.frame_skip=0 must be an integer >= 1"),
        ({"kwargs": {"device": "cuda:99"}}, r"env.kwargs.device='cuda:99': this machine's torch"),
        (
            {"observation_keys": ["position", "position"]},
            r"env.observation_keys=\['position', 'position'\] names \['position'\] more than",
        ),
        (
            {"force_adapter": "none", "force_key": "position"},
            r"force key 'position' \(env.force_key\) has shape \[4\], not the \[n_sites",
        ),
    ],
)
def test_an_external_envs_settings_are_checked_before_anything_is_written(tmp_path, env, match):
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    with pytest.raises(ValueError, match=match) as err:
        cfg = make_config(
            variant="r+rf", run_dir=str(tmp_path / "run"),
            env={"name": "dm_control:finger-spin", **env},
        )  # fmt: skip
        train(cfg)
    assert "\n" not in str(err.value).removeprefix("invalid training config:\n  - ")
    assert list(tmp_path.iterdir()) == []
