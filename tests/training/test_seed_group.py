"""SeedGroup: several seeds of one run in one process, their updates one batched step."""

import pytest
import torch

from gentlerl.config.layout import RunLayout
from gentlerl.files import LinkRefusedError
from gentlerl.training import train
from gentlerl.training.run_lock import RunLock, RunLockedError
from gentlerl.training.seed_group import SeedGroup, group_problems, train_seeds
from tests.helpers import read_scalar, tiny_config, toy_env

NAMES = (
    "train/loss_value",
    "train/loss_actor",
    "train/model_penalty",
    "eval/return",
    "eval/max_impact_mean",
)


def _group(root, seeds=(0, 1), **overrides):
    return [tiny_config(root / f"seed{s}", seed=s, **overrides) for s in seeds]


@pytest.fixture(scope="module")
def group_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("group")
    group = SeedGroup(_group(root, total_frames=600), toy_env)
    summaries = group.run()
    return root, group, summaries


def test_each_seed_is_a_finished_run_of_its_own_that_learned(group_runs):
    root, group, summaries = group_runs
    assert len(summaries) == 2 and all("success_rate" in s for s in summaries)
    for s in (0, 1):
        assert (root / f"seed{s}" / "DONE").exists()
        losses = read_scalar(root / f"seed{s}", "train/loss_value")
        assert len(losses) == 4  # 0.5 updates per frame after 200 random: 200 updates, every 50
    first = [v for _, v in read_scalar(root / "seed0", "train/loss_value")]
    other = [v for _, v in read_scalar(root / "seed1", "train/loss_value")]
    assert first != other  # two seeds, not one twice


def test_each_seeds_actor_is_its_row_of_the_batched_learner(group_runs):
    """The saved policy of seed s acts with row s of the stacked parameters (shared, no copy)."""
    root, group, _ = group_runs
    for s in (0, 1):
        saved = torch.load(root / f"seed{s}" / "checkpoint.pt", weights_only=False)["actor"]
        rows = list(group.learner.params["actor"][s].values(True, True))
        assert len(rows) == len(saved) > 0
        for value in rows:
            assert any(v.shape == value.shape and torch.equal(v, value) for v in saved.values())
        for v in saved.values():  # its own row only, not the whole stack the row is a view of
            assert v.untyped_storage().nbytes() == v.numel() * v.element_size()
    one, two = (group.learner.params["actor"][s] for s in (0, 1))
    assert not all(
        torch.equal(a, b)
        for a, b in zip(one.values(True, True), two.values(True, True), strict=True)
    )


def test_a_group_reproduces_itself(group_runs, tmp_path):
    root, _, _ = group_runs
    train_seeds(_group(tmp_path, total_frames=600), toy_env)
    for s in (0, 1):
        for name in NAMES:
            again = read_scalar(tmp_path / f"seed{s}", name)
            assert again == read_scalar(root / f"seed{s}", name), (s, name)


def test_a_seeds_checkpoint_resumes_as_a_run_of_its_own(group_runs, tmp_path):
    """Its optimisers hold its rows of the batched Adam: it goes on alone to 800 frames."""
    root, _, _ = group_runs
    import shutil

    shutil.copytree(root / "seed1", tmp_path / "seed1")
    (tmp_path / "seed1" / "DONE").unlink()
    state = torch.load(tmp_path / "seed1" / "checkpoint.pt", weights_only=False)
    moments = state["learner"]["optimizer"]["state"]
    assert moments and all(m["exp_avg"].abs().sum() > 0 for m in moments.values())
    cfg = tiny_config(tmp_path / "seed1", seed=1, total_frames=800, resume=True)
    train(cfg, toy_env)
    assert read_scalar(tmp_path / "seed1", "train/loss_value")[-1][0] == 800


def test_a_group_is_refused_in_one_line_before_any_run(tmp_path):
    other = _group(tmp_path, seeds=(0,))[0]
    lr = tiny_config(tmp_path / "b", seed=1, learner={"lr_actor": 1e-3})
    assert group_problems([other, lr]) == ["seed 1's config differs from seed 0's in ['learner']"]
    same_dir = [other, tiny_config(tmp_path / "seed0", seed=1)]
    assert "each seed needs its own run_dir" in group_problems(same_dir)[0]
    steered = _group(tmp_path, tolerance=2.0, multiplier="pid")
    with pytest.raises(ValueError, match="a seed group batches one penalty weight"):
        SeedGroup(steered, toy_env)
    assert not any(tmp_path.glob("seed*/checkpoint.pt"))
    with pytest.raises(ValueError, match="needs at least one config"):
        SeedGroup([], toy_env)


def test_a_group_refuses_a_checkpoint_but_reruns_a_group_stopped_before_its_first(tmp_path):
    """A run_dir with a checkpoint is refused before any lock or folder; one holding only the
    logs of a group stopped before its first checkpoint starts again (resume=auto)."""
    cfgs = _group(tmp_path, total_frames=300, resume="auto")
    stale = RunLayout(tmp_path / "seed1").scalars / "stale.csv"
    stale.parent.mkdir(parents=True)
    stale.write_text("5,1.0\n")
    train_seeds(cfgs, toy_env)
    assert (tmp_path / "seed1" / "DONE").exists()
    assert read_scalar(tmp_path / "seed1", "stale") == []  # the stopped run's logs cut
    with pytest.raises(ValueError, match="holds a checkpoint: a seed group does not resume"):
        train_seeds(_group(tmp_path, total_frames=300, resume="auto"), toy_env)


def test_an_icm_group_trains_its_models_as_one_step(tmp_path):
    """ICM's loss has a pure losses(batch, params) too: its seeds step as one ModelStep."""
    group = SeedGroup(_group(tmp_path, variant="r+icm", total_frames=300), toy_env)
    assert group.models["icm"].num_seeds == 2
    group.run()
    for s in (0, 1):
        assert len(read_scalar(tmp_path / f"seed{s}", "train/model_icm")) >= 1


def test_the_vmapped_rescoring_trains_the_group_as_the_seed_by_seed_one(group_runs, tmp_path):
    """The GPU's path (one vmapped r^sp forward of every seed's target model) run on the CPU:
    the group logs what the CPU's seed-by-seed re-scoring logged, to float rounding."""
    from gentlerl.rewards.window_rescore import WindowRescorer

    root, _, _ = group_runs
    group = SeedGroup(_group(tmp_path, total_frames=600), toy_env)
    group.rescorer = WindowRescorer([t.rewards for t in group.trainers], vmapped=True)
    group.run()
    for s in (0, 1):
        for name in ("train/loss_value", "train/penalty_surprise_per_contact_step"):
            got = read_scalar(tmp_path / f"seed{s}", name)
            expected = read_scalar(root / f"seed{s}", name)
            assert [f for f, _ in got] == [f for f, _ in expected] == [300, 400, 500, 600]
            assert [v for _, v in got] == pytest.approx([v for _, v in expected], rel=1e-4)
        assert abs(read_scalar(tmp_path / f"seed{s}", name)[-1][1]) > 0.01  # r^sp was on


def test_a_group_refuses_a_planted_link_before_writing_anything(tmp_path):
    """Each seed's folder is checked as a lone run's is (its run lock): a planted
    eval_episodes.csv link is refused, the file it names untouched, no seed's folder left."""
    outside = tmp_path / "outside.csv"
    outside.write_text("keep\n")
    cfgs = _group(tmp_path / "g", total_frames=300, resume="auto")
    (tmp_path / "g" / "seed1").mkdir(parents=True)
    (tmp_path / "g" / "seed1" / "eval_episodes.csv").symlink_to(outside)
    with pytest.raises(LinkRefusedError, match="holds 1 symbolic link"):
        train_seeds(cfgs, toy_env)
    assert outside.read_text() == "keep\n" and not (tmp_path / "g" / "seed0").exists()


def test_a_group_and_a_lone_run_of_one_of_its_seeds_exclude_each_other(tmp_path):
    """One writer per run directory: while a seed's folder is locked (a lone `gentlerl train`
    of it, or its group), the other is refused before it writes."""
    cfgs = _group(tmp_path, total_frames=300, resume="auto")
    with RunLock(cfgs[1].run_dir), pytest.raises(RunLockedError, match="is in use by pid"):
        train_seeds(cfgs, toy_env)
    assert not (tmp_path / "seed0").exists()
    with RunLock(cfgs[1].run_dir), pytest.raises(RunLockedError, match="is in use by pid"):
        train(tiny_config(tmp_path / "seed1", seed=1, total_frames=300, resume="auto"), toy_env)


def test_a_group_of_three_seeds_is_its_seeds_alone_over_their_first_50_updates(tmp_path):
    """Each seed draws from its own random streams (exploration noise, replay and model
    samples) and the vmapped step is each seed's own: a group's logs are its seeds' lone runs',
    to 1e-5, over 300 frames (50 updates)."""
    seeds = (0, 1, 2)
    train_seeds(_group(tmp_path / "group", seeds=seeds, total_frames=300), toy_env)
    names = (*NAMES, "train/batch_reward", "train/batch_penalty", "train/value_reward")
    for s in seeds:
        alone = tmp_path / "alone" / f"seed{s}"
        train(tiny_config(alone, seed=s, total_frames=300), toy_env)
        for name in names:
            got, want = read_scalar(tmp_path / "group" / f"seed{s}", name), read_scalar(alone, name)
            assert [f for f, _ in got] == [f for f, _ in want] and want, (s, name)
            assert [v for _, v in got] == pytest.approx([v for _, v in want], rel=1e-5, abs=1e-6)


def test_a_group_with_normalised_heads_trains_each_seed_as_its_lone_run(tmp_path):
    """learner.normalize_values divides each head by its own batch's magnitude: inside the
    group's vmap that is each seed's batch, so a seed's losses are its lone run's."""
    over = dict(variant="r+rf", learner=dict(normalize_values=True), total_frames=300)
    SeedGroup(_group(tmp_path / "group", **over), toy_env).run()
    train(tiny_config(tmp_path / "lone", seed=1, **over), toy_env)
    grouped = read_scalar(tmp_path / "group" / "seed1", "train/loss_actor")
    lone = read_scalar(tmp_path / "lone", "train/loss_actor")
    assert len(grouped) >= 1
    for (step_g, value_g), (step_l, value_l) in zip(grouped, lone, strict=True):
        assert step_g == step_l and value_g == pytest.approx(value_l, rel=1e-4, abs=1e-5)


def test_a_group_whose_buffers_cannot_fit_the_free_memory_is_refused_before_any_folder(
    tmp_path, monkeypatch
):
    """The finding: 64 seeds of the default recipe grew to the machine's memory and failed.
    The toy env's step (both observations): its bytes x (the learner's and the models' kept
    transitions, each at most the 300 frames) x 2 seeds is the least the group keeps; one byte
    short of it is refused, in one line."""
    from gentlerl.training import seed_group

    cfgs = [tiny_config(tmp_path / f"s{seed}", seed=seed, total_frames=300) for seed in (0, 1)]
    env = toy_env()
    per_frame = env.rand_step(env.reset()).bytes()
    need = 2 * (300 + 300) * per_frame
    monkeypatch.setattr(seed_group, "available_memory", lambda: need - 1)
    with pytest.raises(
        ValueError, match=r"2 seeds would keep at least .* GB of transitions \(600 a seed x"
    ):
        train_seeds(cfgs, toy_env)
    assert not any(tmp_path.iterdir())  # nothing made
    monkeypatch.setattr(seed_group, "available_memory", lambda: need)
    assert seed_group.group_memory_problem(cfgs, toy_env) is None
    monkeypatch.setattr(seed_group, "available_memory", lambda: None)  # not Linux: not judged
    assert seed_group.group_memory_problem(cfgs, toy_env) is None


def test_the_free_memory_is_read_from_the_kernel():
    free = __import__("gentlerl.training.seed_group", fromlist=["x"]).available_memory()
    assert free is None or 0 < free < 2**50
