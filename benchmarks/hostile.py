"""Issue 55's hostile-input findings re-run against a source tree, each outcome classified.

Each probe re-runs one named finding of issue 55 ("Hostile inputs V") in a fresh temporary folder
(``tempfile``), against the tree whose ``src/`` is given (``--src PATH``: the probes' Python
processes get ``PATH`` and the tree's root, for its ``tests/toy_env.py``, as ``PYTHONPATH``; the
shell probes run that tree's ``benchmarks/device_check.sh``). Each probe names the test that
covers its finding now, and answers one class:

``refused``
    a clear error (one line, naming the value) and nothing written or changed;
``safe``
    accepted and made safe: it behaves correctly (the probe checks how);
``security``
    a file outside the run written through a planted link (or read through it: its text copied
    into the run), or code run from a folder another user could have planted;
``lost``
    a run's rows or checkpoint written by two writers at once, or a run that can no longer be run
    again (its folders block it);
``hang``
    no answer within the probe's time limit (the process group is killed);
``traceback``
    a crash: a traceback, or an error that is not a refusal of the input;
``silent non-finite``
    a NaN or inf taken in without a word (read as a number, kept in a state);
``silent accept``
    an out-of-range input taken without a word;
``late refusal``
    the input passes the checks and fails later, after the run started or wrote;
``n/a (not in this version)``
    what the probe calls does not exist in the tree probed.

The 10,000-seed probe runs under a 4 GiB address-space limit and 30 s (the code before the seed
bound spent 7.3 GB on it); the others answer in seconds (a tiny toy run of 100 frames where a run
is needed). ``device_check.sh``'s site probe plants a folder in a private ``/tmp`` (a mount
namespace, ``unshare --mount``; as root), never in the machine's own ``/tmp``.

Run: ``python benchmarks/hostile.py [--src PATH] [--note "before the fixes"] [--record]``
(``--src`` default: this checkout's ``src``; another commit's: ``git worktree add DIR COMMIT``,
then ``--src DIR/src``). With ``--record`` the table, with the machine, its load, the date and
the commit of the tree probed, is appended to ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "RESULTS.md"

if str(ROOT / "benchmarks") not in sys.path:  # mutation.py's machine(), run as a script or not
    sys.path.insert(0, str(ROOT / "benchmarks"))
from mutation import machine  # noqa: E402

CLASSES = (
    "refused",
    "safe",
    "security",
    "lost",
    "hang",
    "traceback",
    "silent non-finite",
    "silent accept",
    "late refusal",
    "n/a (not in this version)",
)
#: The classes the closing note of issue 55 needs at 0 after the fixes.
BAD = ("security", "lost", "hang", "traceback", "silent non-finite")
NA = "n/a (not in this version)"
#: What a child process prints before its outcome (the last line of its stdout).
MARK = "HOSTILE-OUTCOME "
#: A child's time limit, s (a tiny toy run, or the real hand's evaluation env, takes a few).
CHILD_LIMIT = 120
#: The 10,000-seed probe's limits: wall time (s) and address space (bytes).
SEEDS_LIMIT, SEEDS_MEMORY = 30, 4 << 30

Outcome = tuple[str, str]


@dataclass(frozen=True)
class Probe:
    """One finding re-run: its name, the finding, the test that covers it now, and its run
    (``run(work, src) -> (class, detail)``, in the fresh folder ``work``)."""

    name: str
    finding: str
    test: str
    run: Callable[[Path, Path], Outcome]


class Missing(Exception):
    """What a probe calls is not in the tree probed."""


class Started(BaseException):
    """The stand-in for ``gentlerl train``'s training was reached: the config was accepted."""


# ---------------------------------------------------------------------------------------------
# Child side: run with the probed tree's gentlerl on PYTHONPATH, cwd the probe's fresh folder.


def need(module: str, name: str) -> Any:
    """``module.name`` of the probed tree, or :class:`Missing`."""
    import importlib

    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as err:
        raise Missing(f"{module}.{name}: {err}") from None


def call(fn: Callable[[], Any]) -> Exception | None:
    """The exception ``fn()`` raised (``None``: it returned)."""
    try:
        fn()
    except Exception as err:  # noqa: BLE001 - what it raised is the probe's finding
        return err
    return None


def refusal(err: BaseException, clean: bool) -> Outcome:
    """``refused`` for a one-line ``ValueError`` / ``TypeError`` / ``OSError`` / ``SystemExit``
    that left nothing behind (``clean``); ``late refusal`` when it left something; else
    ``traceback``."""
    text = str(err.code if isinstance(err, SystemExit) else err).strip()
    named = f"{type(err).__name__}: {text}"
    if not isinstance(err, ValueError | TypeError | OSError | SystemExit) or not text:
        return "traceback", named
    if "\n" in text:
        return "traceback", f"a refusal of {text.count(chr(10)) + 1} lines: {named}"
    return ("refused", named) if clean else ("late refusal", f"{named} (after writing)")


def tiny_group(root: Path, seeds: tuple[int, ...] = (0, 1)) -> list[Any]:
    """The tests' tiny toy configs of a seed group, 100 frames each (no update: collection, the
    closing evaluation and checkpoint), ``resume=auto`` as ``gentlerl seeds`` sets it."""
    from tests.helpers import tiny_config

    return [
        tiny_config(
            root / f"seed{s}", seed=s, total_frames=100, init_random_frames=100, resume="auto"
        )
        for s in seeds
    ]


def child_seeds_lock(work: Path) -> Outcome:
    """A group of seeds 0 and 1 while a lone run of seed 1 holds its folder (its run lock)."""
    from tests.helpers import toy_env

    lock = need("gentlerl.training.run_lock", "RunLock")
    train_seeds = need("gentlerl.training.seed_group", "train_seeds")
    cfgs = tiny_group(work / "g")
    with lock(cfgs[1].run_dir):  # what a lone `gentlerl train` of seed 1 holds while it runs
        err = call(lambda: train_seeds(cfgs, toy_env))
        written = sorted(p.name for p in Path(cfgs[1].run_dir).iterdir() if p.name != ".lock")
    if err is None:
        return "lost", f"both ran: the group wrote {written} into seed1 beside its lone run"
    return refusal(err, clean=not written and not (work / "g" / "seed0").exists())


def child_seeds_link(work: Path) -> Outcome:
    """A group whose seed 1 folder holds a planted ``eval_episodes.csv`` link to a file outside."""
    from tests.helpers import toy_env

    train_seeds = need("gentlerl.training.seed_group", "train_seeds")
    outside = work / "outside.csv"
    outside.write_text("keep\n")
    cfgs = tiny_group(work / "g")
    (work / "g" / "seed1").mkdir(parents=True)
    (work / "g" / "seed1" / "eval_episodes.csv").symlink_to(outside)
    err = call(lambda: train_seeds(cfgs, toy_env))
    if outside.read_text() != "keep\n":
        return "security", f"written through the link: outside.csv now {outside.stat().st_size} B"
    copy = work / "g" / "seed1" / "eval_episodes.csv"
    if copy.is_file() and not copy.is_symlink() and copy.read_text().startswith("keep"):
        return "security", "read through the link: the outside file's text copied into the run"
    if err is None:
        return "safe", "trained; the file the link names untouched"
    return refusal(err, clean=not (work / "g" / "seed0").exists())


def child_group_rerun(work: Path) -> Outcome:
    """A group stopped before its first checkpoint (seed 1 holds logs, no checkpoint), re-run."""
    from tests.helpers import toy_env

    train_seeds = need("gentlerl.training.seed_group", "train_seeds")
    cfgs = tiny_group(work / "g")
    stale = Path(cfgs[1].run_dir) / "logs" / "scalars" / "stale.csv"
    stale.parent.mkdir(parents=True)
    stale.write_text("5,1.0\n")
    err = call(lambda: train_seeds(cfgs, toy_env))
    if err is not None:
        kind, text = refusal(err, clean=True)
        if kind == "traceback":
            return kind, text
        return "lost", f"its re-run refused, its folders block it: {text}"
    done = all((Path(c.run_dir) / "DONE").exists() for c in cfgs)
    cut = not stale.exists() or not stale.read_text().strip()
    if done and cut:
        return "safe", "re-run to DONE, the stopped run's rows cut"
    return "lost", f"re-run: DONE={done}, the stopped run's rows kept={not cut}"


def train_cli(args: list[str], stand_in: Callable[[Any], None]) -> tuple[list[Any], BaseException]:
    """``gentlerl train ARGS`` in this process, its training replaced by ``stand_in(cfg)`` then
    :class:`Started`: the configs that reached it and what ended the command."""
    import gentlerl.training.loop as loop
    from gentlerl import cli

    reached: list[Any] = []

    def train(cfg: Any, *_: Any, **__: Any) -> None:
        reached.append(cfg)
        stand_in(cfg)
        raise Started

    loop.train = train
    try:
        cli.main(["train", *args, "run_dir=run"])
    except (SystemExit, Started) as end:
        return reached, end
    return reached, SystemExit(0)


def cli_outcome(work: Path, reached: list[Any], end: BaseException, accepted: str) -> Outcome:
    """The class of a :func:`train_cli` end: ``accepted`` when the stand-in was reached."""
    if isinstance(end, Started):
        return "silent accept", accepted
    if reached:  # refused after the config was taken: by the run's own first steps
        return "late refusal", f"config accepted, then: {end.code}"
    return refusal(end, clean=not any(work.iterdir()))


def child_seed_max(work: Path) -> Outcome:
    """``gentlerl train seed=4294967295``, its run stopped after its first seeding: the
    evaluation env's (seed + EVAL_SEED_OFFSET), on the hand as ``train`` builds it."""

    def first_steps(cfg: Any) -> None:
        from gentlerl.training.builders import default_env_factory, make_run_eval_env

        make_run_eval_env(cfg, default_env_factory(cfg)).close()

    reached, end = train_cli(["seed=4294967295"], first_steps)
    return cli_outcome(work, reached, end, "the run started and seeded its evaluation env")


def child_compile_int(work: Path) -> Outcome:
    """``gentlerl train learner.compile=1``: an integer where a boolean goes."""
    seen: list[Any] = []
    reached, end = train_cli(["learner.compile=1"], lambda cfg: seen.append(cfg.learner.compile))
    value = seen[0] if seen else None
    return cli_outcome(work, reached, end, f"the run started with learner.compile={value!r}")


def child_sweep_file_yes(work: Path) -> Outcome:
    """``gentlerl sweep FILE --out OUT --dry-run``, the file setting ``learner.compile: {values:
    [yes]}``: a YAML 1.1 boolean word in a sweep file (planned only, nothing trains)."""
    import contextlib
    import io

    from gentlerl import cli

    path = work / "sweep.yaml"
    path.write_text("parameters: {learner.compile: {values: [yes]}}\n")
    err, out = io.StringIO(), io.StringIO()
    argv = ["sweep", str(path), "--out", str(work / "out"), "--dry-run"]
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = cli.main(argv)
    except SystemExit as exit_:
        return refusal(exit_, clean=not (work / "out").exists())
    text = err.getvalue().strip()
    if code == 0 or not text:
        return "silent accept", f"rc {code}: planned {last_line(out.getvalue())!r}"
    return refusal(SystemExit(text), clean=not (work / "out").exists())


def child_seeds_set_yes(work: Path) -> Outcome:
    """``gentlerl seeds 0 1 --set learner.compile=yes --out OUT``: a word where a boolean goes,
    on the command line of a group (its training replaced by a stand-in)."""
    import contextlib
    import io

    import gentlerl.training.seed_group as seed_group
    from gentlerl import cli

    seen: list[Any] = []

    def train_seeds(cfgs: Any, *_: Any) -> None:
        seen.append(cfgs[0].learner.compile)
        raise Started

    seed_group.train_seeds = train_seeds
    err = io.StringIO()
    argv = ["seeds", "0", "1", "--set", "learner.compile=yes", "--out", str(work / "out")]
    try:
        with contextlib.redirect_stderr(err):
            code = cli.main(argv)
    except Started:
        return "silent accept", f"the group started with learner.compile={seen[0]!r}"
    text = err.getvalue().strip()
    if code == 0 or not text:
        return "silent accept", f"rc {code}, nothing said"
    return refusal(SystemExit(text), clean=not (work / "out").exists())


def child_tolerance(work: Path) -> Outcome:
    """``gentlerl train gentleness.tolerance=1e300``: what a 9 N impact costs at the run's
    tolerance (eq. 5's penalty of the impact in units of the tolerance)."""
    costs: list[float] = []

    def penalty(cfg: Any) -> None:
        import torch

        from gentlerl.functional import impact_penalty, tolerance_unit

        unit = tolerance_unit(cfg.gentleness.tolerance)
        costs.append(impact_penalty(torch.tensor([9.0]) / unit).item())

    reached, end = train_cli(["gentleness.tolerance=1e300"], penalty)
    cost = costs[0] if costs else math.nan
    if isinstance(end, Started) and cost != 0.0:
        return "safe", f"accepted; a 9 N impact costs {cost:.3g}"
    return cli_outcome(work, reached, end, f"the run started; a 9 N impact costs {cost}")


def multiplier() -> Any:
    """The tests' multiplier (tolerance 2 N, gains (1, 0.1, 0), cap 5) after two episodes."""
    cls = need("gentlerl.rewards.multiplier", "ImpactMultiplier")
    m = cls(tolerance=2.0, gains=(1.0, 0.1, 0.0), integral_max=5.0)
    m.observe([4.0, 3.0])
    return m


def child_multiplier_state(work: Path, entry: str, value: float) -> Outcome:
    """``ImpactMultiplier.load_state_dict`` of a saved state whose ``entry`` is ``value``."""
    m = multiplier()
    before = repr(m.state_dict())
    err = call(lambda: m.load_state_dict({**m.state_dict(), entry: value}))
    if err is not None:
        return refusal(err, clean=repr(m.state_dict()) == before)
    loaded, weight = m.weight, m.observe([3.0])
    detail = f"{entry}={value} loaded: weight {loaded}, after the next episode {weight}"
    return ("silent accept" if math.isfinite(value) else "silent non-finite"), detail


def child_curiosity_scale(work: Path) -> Outcome:
    """``IntrinsicRewards.load_state_dict`` of a checkpoint whose curiosity scale is (nan, 3)."""
    from tests.toy_env import ToyHandEnv

    config = need("gentlerl.config", "GentlenessConfig")
    rewards_cls = need("gentlerl.rewards", "IntrinsicRewards")
    settings = config(curiosity_norm=True, model_hidden=16, reward_delay=0)
    rewards = rewards_cls.from_env(ToyHandEnv(), "r+rf+rsp", settings)
    rsp = rewards.transform[1]
    before = rsp.curiosity_scale
    state = rewards.state_dict()
    state["curiosity_scales"] = [[math.nan, 3]]
    err = call(lambda: rewards.load_state_dict(state))
    if err is not None:
        return refusal(err, clean=rsp.curiosity_scale == before)
    mean, count = rsp.curiosity_scale
    kind = "silent non-finite" if not math.isfinite(mean) else "safe"
    return kind, f"loaded: curiosity_scale=({mean}, {count})"


def child_observe_nan(work: Path) -> Outcome:
    """``ImpactMultiplier.observe_batch`` of one episode whose impacts are 9 N, NaN, 0.5 N."""
    import torch
    from tensordict import TensorDict

    from gentlerl import keys

    m = need("gentlerl.rewards.multiplier", "ImpactMultiplier")(2.0, (1.0, 0.1, 0.0))
    done = torch.tensor([[False], [False], [True]])
    batch = TensorDict(
        {
            ("collector", "traj_ids"): torch.zeros(3, dtype=torch.int64),
            ("next", keys.IMPACT): torch.tensor([[9.0], [math.nan], [0.5]]),
            ("next", keys.DONE): done,
        },
        batch_size=[3],
    )
    err = call(lambda: m.observe_batch(batch))
    if err is not None:
        return refusal(err, clean=m.episodes == 0 and m.weight == 1.0)
    seen = list(m.recent)
    return "silent non-finite", f"observed the episode's max impact as {seen} N (it held 9 N, NaN)"


def child_pid_gain(work: Path) -> Outcome:
    """``functional.constraint.pid_lagrangian`` with the gains (NaN, 0.1, 0)."""
    pid = need("gentlerl.functional.constraint", "pid_lagrangian")
    out: list[Any] = []
    err = call(lambda: out.append(pid(1.0, 0.0, 0.0, 1.0, (math.nan, 0.1, 0.0))))
    if err is not None:
        return refusal(err, clean=True)
    return "silent non-finite", f"K_P=nan taken: (mu, integral) = {out[0]}"


def child_multiplier_gain(work: Path) -> Outcome:
    """``ImpactMultiplier`` built with the gains (NaN, 0.1, 0), then an episode of 4 N."""
    cls = need("gentlerl.rewards.multiplier", "ImpactMultiplier")
    made: list[Any] = []
    err = call(lambda: made.append(cls(tolerance=2.0, gains=(math.nan, 0.1, 0.0))))
    if err is not None:
        return refusal(err, clean=True)
    weight = made[0].observe([4.0])
    return "silent non-finite", f"gains (nan, 0.1, 0) taken; weight after a 4 N episode {weight}"


def child_learner_lr(work: Path, lr: float) -> Outcome:
    """``Learner(lr_actor=lr)`` on the tests' small D4PG loss."""
    learner = need("gentlerl.agent.learner", "Learner")
    from gentlerl.models import make_actor, make_critic
    from gentlerl.objectives import MultiHeadD4PGLoss

    critic = make_critic(3, 1, 2, (16,), 11, v_min=-5.0, v_max=5.0)
    loss = MultiHeadD4PGLoss(make_actor(3, 1, (16,)), critic, reward_keys=["reward", "penalty"])
    err = call(lambda: learner(loss, lr_actor=lr, lr_critic=1e-3, target_update_period=2))
    if err is not None:
        return refusal(err, clean=True)
    return "silent non-finite", f"lr_actor={lr} taken by the learner's optimiser"


CHILDREN: dict[str, Callable[[Path], Outcome]] = {
    "seeds-lock": child_seeds_lock,
    "seeds-link": child_seeds_link,
    "group-rerun": child_group_rerun,
    "seed-max": child_seed_max,
    "compile-int": child_compile_int,
    "seeds-set-yes": child_seeds_set_yes,
    "sweep-file-yes": child_sweep_file_yes,
    "tolerance-1e300": child_tolerance,
    "multiplier-state-nan": lambda w: child_multiplier_state(w, "multiplier", math.nan),
    "multiplier-state-negative": lambda w: child_multiplier_state(w, "multiplier", -1.0),
    "curiosity-scale-nan": child_curiosity_scale,
    "observe-batch-nan": child_observe_nan,
    "pid-gain-nan": child_pid_gain,
    "multiplier-gain-nan": child_multiplier_gain,
    "learner-lr-nan": lambda w: child_learner_lr(w, math.nan),
    "learner-lr-inf": lambda w: child_learner_lr(w, math.inf),
}


def child_main(name: str) -> None:
    """Run probe ``name`` here (cwd: its folder) and print its outcome as the last line."""
    os.environ.setdefault("RL_LOGGING_LEVEL", "WARNING")
    try:
        kind, detail = CHILDREN[name](Path.cwd())
    except Missing as err:
        kind, detail = NA, str(err)
    print(MARK + json.dumps({"class": kind, "detail": detail}), flush=True)


# ---------------------------------------------------------------------------------------------
# Parent side: each probe in a fresh folder, a process of its own.


def run_limited(
    command: list[str], cwd: Path, env: dict[str, str], limit: float, memory: int | None = None
) -> tuple[int | None, str, str]:
    """``command`` in its own session under ``nice``, killed whole after ``limit`` s (return
    code ``None``); ``memory``: its address-space limit in bytes."""

    def limits() -> None:
        os.nice(10)
        if memory is not None:
            resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    proc = subprocess.Popen(
        command, cwd=cwd, env=env, text=True, start_new_session=True, preexec_fn=limits,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        out, err = proc.communicate(timeout=limit)
        return proc.returncode, out, err
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        return None, out, err


def python_env(src: Path) -> dict[str, str]:
    """This environment with the probed tree's ``src`` and root first on ``PYTHONPATH``."""
    path = f"{src}{os.pathsep}{src.parent}"
    return {**os.environ, "PYTHONPATH": path, "RL_LOGGING_LEVEL": "WARNING"}


def last_line(text: str) -> str:
    """The last line of ``text`` that is not a warning."""
    lines = [ln for ln in text.strip().splitlines() if ln.strip() and "Warning" not in ln]
    return lines[-1].strip() if lines else ""


def in_child(name: str) -> Callable[[Path, Path], Outcome]:
    """The probe that runs :data:`CHILDREN` ``[name]`` in a Python process of its own."""

    def run(work: Path, src: Path) -> Outcome:
        command = [sys.executable, str(Path(__file__).resolve()), "--child", name]
        code, out, err = run_limited(command, work, python_env(src), CHILD_LIMIT)
        if code is None:
            return "hang", f"no answer in {CHILD_LIMIT} s"
        for line in reversed(out.splitlines()):
            if line.startswith(MARK):
                found = json.loads(line[len(MARK) :])
                return found["class"], found["detail"]
        return "traceback", f"rc {code}: {last_line(err)}"

    return run


def probe_seeds_10000(work: Path, src: Path) -> Outcome:
    """``gentlerl seeds 0 1 ... 9999 --out OUT``: refused before any folder, or not (then it is
    stopped by :data:`SEEDS_LIMIT` / :data:`SEEDS_MEMORY`)."""
    command = [sys.executable, "-m", "gentlerl", "seeds", *map(str, range(10_000))]
    command += ["--out", str(work / "out")]
    start = time.perf_counter()
    code, _, err = run_limited(command, work, python_env(src), SEEDS_LIMIT, SEEDS_MEMORY)
    wall = time.perf_counter() - start
    out = work / "out"
    left = sum(1 for _ in out.iterdir()) if out.is_dir() else 0
    if code is None:
        return "hang", f"no refusal in {SEEDS_LIMIT} s (killed); {left} seed folders left"
    line = last_line(err)
    if code == 0:
        return "silent accept", f"rc 0 in {wall:.0f} s; {left} seed folders"
    if "Traceback" in err or "MemoryError" in err:
        return "traceback", f"rc {code} in {wall:.0f} s, {left} folders left: {line}"
    if left:
        return "late refusal", f"rc {code} in {wall:.0f} s, {left} folders left: {line}"
    return "refused", f"rc {code} in {wall:.1f} s, no folder: {line}"


#: A stand-in python for device_check.sh: it records the first folder of its PYTHONPATH (the
#: unpacked site) with its mode, owner and whether it holds a planted module, and has nothing.
STUB = """#!/bin/sh
site="${PYTHONPATH%%:*}"
[ -f "$site/site_marker.py" ] && echo "$site $(stat -c '%a %u' "$site") \\
$([ -f "$site/planted.py" ] && echo planted)" >> "$STUB_LOG"
exit 1
"""


def device_tree(
    work: Path, src: Path, root: Path, site: bool = False
) -> tuple[Path, dict[str, str]]:
    """A copy of the probed tree's ``device_check.sh`` in ``work/tree`` (``site``: with a
    ``.devsite/site.tgz`` holding a marker, which the script unpacks: only in a private
    ``/tmp``, the script before the fix unpacks it into ``/tmp/gentlerl_site``), and the
    environment that runs it with :data:`STUB`; ``root``: where the script sees ``work``."""
    script = src.parent / "benchmarks" / "device_check.sh"
    if not script.is_file():
        raise Missing(f"{script} is not in this tree")
    tree = work / "tree"
    (tree / "benchmarks").mkdir(parents=True)
    (tree / ".devsite").mkdir()
    shutil.copy2(script, tree / "benchmarks" / "device_check.sh")
    stub = work / "python"
    stub.write_text(STUB)
    stub.chmod(0o755)
    if site:
        marker = work / "site_marker.py"
        marker.write_text("")
        with tarfile.open(tree / ".devsite" / "site.tgz", "w:gz") as tar:
            tar.add(marker, arcname="site_marker.py")
    env = {**os.environ, "PYTHON": str(root / "python"), "STUB_LOG": str(root / "stub.log")}
    env.pop("SITE_TGZ", None)
    return root / "tree" / "benchmarks" / "device_check.sh", env


#: Where :func:`probe_device_site`'s script sees its folder: ``work`` is bound on
#: ``work/tmp/probe``, and ``work/tmp`` with it on ``/tmp``, in a mount namespace of its own.
SEEN = Path("/tmp/probe")


def probe_device_site(work: Path, src: Path) -> Outcome:
    """device_check.sh where ``/tmp/gentlerl_site`` was made first by another user (world-
    writable, a ``planted.py`` in it): does its python run with that folder on its path? In a
    private ``/tmp`` (a mount namespace: ``work/tmp`` on ``/tmp``), not the machine's."""
    script, env = device_tree(work, src, SEEN, site=True)
    private = work / "tmp"
    planted = private / "gentlerl_site"
    planted.mkdir(parents=True)
    (private / SEEN.name).mkdir()
    (planted / "planted.py").write_text("print('planted')\n")
    planted.chmod(0o777)
    os.chown(planted, 65534, 65534)
    env["TMPDIR"] = "/tmp"
    inner = (
        'mount --bind "$1" "$1/tmp/$2" && mount --rbind "$1/tmp" /tmp && exec bash "$3" "$4" env'
    )
    args = [str(work), SEEN.name, str(script), str(SEEN / "out")]
    command = ["unshare", "--mount", "--propagation", "private", "bash", "-c", inner, "_", *args]
    code, _, err = run_limited(command, work, env, 60)
    log = work / "stub.log"
    if code is None:
        return "hang", "device_check.sh env: no answer in 60 s"
    if not log.exists():
        return NA, f"no site unpacked (needs unshare --mount, as root): rc {code} {last_line(err)}"
    seen = log.read_text().split()
    if "planted" in seen:
        return "security", f"python ran with {seen[0]} (another user's, planted.py in it) first"
    left = sorted(p.name for p in private.iterdir() if p.name not in (planted.name, SEEN.name))
    if seen[1:3] == ["700", str(os.getuid())] and not left:
        return "safe", f"a private site ({seen[0]}, mode 700), removed on exit"
    return "security", f"site {seen[0]} mode {seen[1]} owner {seen[2]}; left in /tmp: {left}"


def probe_device_table_link(work: Path, src: Path) -> Outcome:
    """device_check.sh with ``OUT_DIR/device_table.md`` planted as a link to a file outside."""
    script, env = device_tree(work, src, work)
    (work / "tmp").mkdir()
    env["TMPDIR"] = str(work / "tmp")
    out, victim = work / "out", work / "victim"
    out.mkdir()
    victim.write_text("precious\n")
    (out / "device_table.md").symlink_to(victim)
    code, _, err = run_limited(["bash", str(script), str(out), "env"], work, env, 60)
    if code is None:
        return "hang", "device_check.sh env: no answer in 60 s"
    if victim.read_text() != "precious\n":
        return "security", f"rc {code}; the table written through the link into {victim.name}"
    others = sorted(p.name for p in out.iterdir() if p.name != "device_table.md")
    if code == 0:
        return "safe", f"rc 0; the link's target untouched; OUT_DIR holds {others}"
    one = len([ln for ln in err.strip().splitlines() if ln.strip()]) == 1
    kind = "refused" if one and not others else "late refusal" if one else "traceback"
    return kind, f"rc {code}: {last_line(err)}"


def device_probe(fn: Callable[[Path, Path], Outcome]) -> Callable[[Path, Path], Outcome]:
    """``fn``, a missing script answered as ``n/a``."""

    def run(work: Path, src: Path) -> Outcome:
        try:
            return fn(work, src)
        except Missing as err:
            return NA, str(err)

    return run


TESTS = {
    "seeds-lock": "tests/training/test_seed_group.py::"
    "test_a_group_and_a_lone_run_of_one_of_its_seeds_exclude_each_other",
    "seeds-link": "tests/training/test_seed_group.py::"
    "test_a_group_refuses_a_planted_link_before_writing_anything",
    "device-check-site": "tests/repo/test_device_check.py::"
    "test_the_site_is_unpacked_in_a_private_folder_removed_on_exit",
    "device-check-table-link": "tests/repo/test_device_check.py::"
    "test_a_table_or_log_planted_as_a_link_is_refused_and_its_target_untouched",
    "seeds-10000": "tests/apps/test_seeds.py::"
    "test_more_seeds_than_a_group_holds_are_refused_in_one_line_before_any_folder",
    "seed-max": "tests/config/test_config.py::test_bad_values_raise_one_clear_error",
    "multiplier-state-nan": "tests/rewards/test_multiplier.py::"
    "test_a_tampered_state_is_refused_naming_the_entry_and_leaves_the_multiplier_as_it_was",
    "multiplier-state-negative": "tests/rewards/test_multiplier.py::"
    "test_a_tampered_state_is_refused_naming_the_entry_and_leaves_the_multiplier_as_it_was",
    "curiosity-scale-nan": "tests/transforms/test_transforms_hostile.py::"
    "test_a_checkpoint_with_a_non_finite_curiosity_scale_is_refused_naming_it",
    "tolerance-1e300": "tests/config/test_gentleness.py::"
    "test_a_tolerance_past_its_bound_would_zero_the_penalty_and_is_refused",
    "observe-batch-nan": "tests/rewards/test_multiplier.py::"
    "test_a_nan_impact_beside_a_9_newton_peak_is_refused_not_read_as_0_newtons",
    "pid-gain-nan": "tests/functional/test_constraint.py::"
    "test_the_pid_multiplier_refuses_a_non_finite_number_or_a_bool_naming_it",
    "multiplier-gain-nan": "tests/rewards/test_multiplier.py::"
    "test_non_finite_or_boolean_settings_are_refused_at_construction",
    "learner-lr-nan": "tests/agent/test_learner.py::test_bad_learning_rates_are_refused_in_one_line",
    "learner-lr-inf": "tests/agent/test_learner.py::test_bad_learning_rates_are_refused_in_one_line",
    "compile-int": "tests/apps/test_overrides.py::"
    "test_command_line_errors_are_one_line_naming_the_field_and_the_value",
    "seeds-set-yes": "tests/apps/test_seeds.py::test_a_refused_group_is_one_line_and_makes_no_folder",
    "sweep-file-yes": "tests/apps/test_sweeps_hostile.py::"
    "test_malformed_sweep_files_are_one_line_refusals",
    "group-rerun": "tests/training/test_seed_group.py::"
    "test_a_group_refuses_a_checkpoint_but_reruns_a_group_stopped_before_its_first",
}

FINDINGS = {
    "seeds-lock": "1: `gentlerl seeds` took no run lock (a lone run beside its group)",
    "seeds-link": "1: a group wrote through a planted `eval_episodes.csv` link",
    "device-check-site": "2: device_check.sh ran code from a fixed world-writable /tmp folder",
    "device-check-table-link": "2: device_check.sh wrote through a planted device_table.md link",
    "seeds-10000": "3: no bound on the seed count (10,000 seeds)",
    "seed-max": "4: `seed=4294967295` passed the checks and failed late",
    "multiplier-state-nan": "5: a tampered multiplier state (NaN multiplier) loaded unchecked",
    "multiplier-state-negative": "5: a tampered multiplier state (multiplier -1) loaded unchecked",
    "curiosity-scale-nan": "5: a tampered curiosity scale (NaN mean) loaded unchecked",
    "tolerance-1e300": "6: Method III fields without upper bounds (tolerance 1e300)",
    "observe-batch-nan": "7: `observe_batch` read a NaN impact as 0 N",
    "pid-gain-nan": "8: a NaN PID gain taken (functional.constraint)",
    "multiplier-gain-nan": "8: a NaN gain taken by ImpactMultiplier",
    "learner-lr-nan": "8: a NaN learning rate taken by Learner",
    "learner-lr-inf": "8: an inf learning rate taken by Learner (beside the NaN)",
    "compile-int": "9: `learner.compile=1` on the command line started a run",
    "seeds-set-yes": "9: a word as a boolean in `gentlerl seeds --set` (found re-running 9)",
    "sweep-file-yes": "9: a word as a boolean in a sweep file (found re-running 9)",
    "group-rerun": "10: a group stopped before its first checkpoint could not be re-run",
}

RUNS: dict[str, Callable[[Path, Path], Outcome]] = {
    **{name: in_child(name) for name in CHILDREN},
    "device-check-site": device_probe(probe_device_site),
    "device-check-table-link": device_probe(probe_device_table_link),
    "seeds-10000": probe_seeds_10000,
}

#: Every probe, in the order of issue 55's findings.
PROBES = [Probe(name, FINDINGS[name], TESTS[name], RUNS[name]) for name in FINDINGS]


def run_probes(src: Path, names: list[str] | None = None) -> list[tuple[Probe, str, str, float]]:
    """Each probe (or those in ``names``) in a fresh temporary folder: (probe, class, detail,
    seconds)."""
    rows = []
    for probe in PROBES:
        if names and probe.name not in names:
            continue
        start = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix=f"gentlerl-hostile-{probe.name}-") as work:
            kind, detail = probe.run(Path(work), src)
        seconds = time.perf_counter() - start
        print(f"{probe.name}: {kind} ({seconds:.1f} s): {detail}", file=sys.stderr, flush=True)
        rows.append((probe, kind, detail, seconds))
    return rows


def table(rows: list[tuple[Probe, str, str, float]]) -> list[str]:
    """The markdown table probe x class, then the counts per class."""

    def cell(text: str) -> str:
        text = " ".join(text.split()).replace("|", "\\|")
        return text if len(text) <= 200 else text[:197] + "..."

    lines = ["| probe | finding | test now | class | what happened | s |"]
    lines.append("| --- | --- | --- | --- | --- | ---: |")
    for probe, kind, detail, seconds in rows:
        test = probe.test.split("::")
        lines.append(
            f"| `{probe.name}` | {cell(probe.finding)} | `{test[0].removeprefix('tests/')}::"
            f"{test[1]}` | **{kind}** | {cell(detail)} | {seconds:.1f} |"
        )
    counts = Counter(kind for _, kind, _, _ in rows)
    lines += ["", "| class | probes |", "| --- | ---: |"]
    lines += [f"| {kind} | {counts[kind]} |" for kind in CLASSES]
    return lines


def tree_commit(src: Path) -> str:
    """The probed tree's commit (short), ``+ changes`` when what the probes use (``src/``,
    ``tests/``, ``benchmarks/device_check.sh``) differs from it."""
    git = ["git", "-C", str(src.parent)]
    commit = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    used = ["--", "src", "tests", "benchmarks/device_check.sh"]
    status = [*git, "status", "--porcelain", "--untracked-files=no", *used]
    dirty = subprocess.run(status, capture_output=True, text=True).stdout.strip()
    return (commit.stdout.strip() or "unknown") + (" + changes" if dirty else "")


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--child":
        child_main(sys.argv[2])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--src", type=Path, default=ROOT / "src", help="the tree's src folder")
    parser.add_argument("--only", nargs="+", choices=[p.name for p in PROBES], help="these probes")
    parser.add_argument("--note", default="", help="a line for the record, e.g. 'before'")
    parser.add_argument("--record", action="store_true", help=f"append the table to {RESULTS}")
    args = parser.parse_args()
    src = args.src.resolve()
    if not (src / "gentlerl").is_dir():
        sys.exit(f"--src {src}: no gentlerl package there")
    command = "python benchmarks/hostile.py " + shlex.join(sys.argv[1:])
    nproc, model, load_before = machine()
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    commit = tree_commit(src)
    start = time.perf_counter()
    rows = run_probes(src, args.only)
    wall = time.perf_counter() - start
    bad = sum(kind in BAD for _, kind, _, _ in rows)
    section = [
        f"## hostile inputs: issue 55's findings re-run at {commit} "
        f"(`benchmarks/hostile.py`, {date})",
        "",
        f"{nproc} cores, {model}; load before: `{load_before}`; after: `{machine()[2]}`. Tree "
        f"probed: commit {commit}; {len(rows)} probes, each in a fresh temporary folder; {wall:.0f}"
        f" s wall.{' ' + args.note if args.note else ''}",
        "",
        f"Command: `{command}`",
        "",
        *table(rows),
        "",
        f"{bad} probe(s) in {', '.join(BAD)}.",
    ]
    text = "\n".join(section) + "\n"
    print(text)
    if args.record:
        with RESULTS.open("a") as f:
            f.write("\n" + text)


if __name__ == "__main__":
    main()
