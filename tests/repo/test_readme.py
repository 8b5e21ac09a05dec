"""The README's code runs as shown: its python blocks verbatim, its ``gentlerl`` commands parse;
so does the code of the docs site's pages that a new user reads next (the drop-in page with the
finger-spin example, the quick start and configuration pages).

The python blocks build their own envs (the hand, dm_control's finger); :class:`PressEnv`, a
small env that is not the hand (3 sensor sites with 2 channels each under the key ``"force"``, a
6-dim observation and 2 actions), is there as ``my_env`` for a block that names one.
"""

import importlib
import re
import shlex
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.envs import EnvBase
from torchrl.envs.utils import check_env_specs

import gentlerl.envs  # noqa: F401  (the GL backend is chosen before a block imports dm_control)
from gentlerl import cli, keys
from gentlerl.functional import impact, impact_penalty
from gentlerl.training.config import iter_fields

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
#: The docs site's pages whose code a new user runs: the drop-in (with the finger example), the
#: quick start and the configuration page.
DROP_IN = ROOT / "docs" / "site" / "torchrl.md"
PAGES = (
    README,
    DROP_IN,
    ROOT / "docs" / "site" / "index.md",
    ROOT / "docs" / "site" / "configuration.md",
)
SITES, CHANNELS, FORCE = 3, 2, "force"


def code_blocks(language: str, path: Path = README) -> list[str]:
    """Every fenced ```language block of ``path`` (the README), in order."""
    return re.findall(rf"^```{language}\n(.*?)^```", path.read_text(), re.M | re.S)


def first_screen(text: str) -> str:
    """What a reader sees first: the README up to the first ``## `` heading after its quick start."""
    quick = text.index("## Quick start")
    return text[: text.index("\n## ", quick + 1)]


class PressEnv(EnvBase):
    """Three pistons pushed by 2 actions (sites 0, 1 by one each, site 2 by both) into springs:
    site i reads [k * depth_i, 0.1 * k * depth_i] (N) once its depth passes 0.
    """

    def __init__(self, stiffness: float = 60.0) -> None:
        super().__init__(batch_size=torch.Size([]))
        self.stiffness = stiffness
        self.observation_spec = Composite(
            {keys.OBSERVATION: Unbounded((2 * SITES,)), FORCE: Unbounded((SITES, CHANNELS))}
        )
        self.action_spec = Bounded(-1.0, 1.0, (2,))
        self.reward_spec = Unbounded((1,))
        self._mix = torch.tensor([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5]])

    def _observe(self, pos: torch.Tensor, vel: torch.Tensor) -> dict[str, torch.Tensor]:
        depth = self.stiffness * pos.clamp_min(0.0)
        return {
            keys.OBSERVATION: torch.cat([pos, vel]),
            FORCE: torch.stack([depth, 0.1 * depth], -1),
        }

    def _reset(self, tensordict: TensorDictBase | None = None) -> TensorDictBase:
        self._pos = torch.zeros(SITES)  # every piston at its spring: a push is felt
        return TensorDict(self._observe(self._pos, torch.zeros(SITES)), [])

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        vel = 0.05 * tensordict[keys.ACTION] @ self._mix
        self._pos = self._pos + vel
        done = torch.zeros(1, dtype=torch.bool)
        out = {**self._observe(self._pos, vel), "reward": torch.zeros(1)}
        return TensorDict({**out, "done": done, "terminated": done.clone()}, [])

    def _set_seed(self, seed: int | None) -> None:
        torch.manual_seed(seed or 0)


def test_the_readme_has_python_blocks():
    assert code_blocks("python"), "README.md has no ```python block"
    assert len(code_blocks("python", DROP_IN)) == 2, "the drop-in page's two examples are gone"


PYTHON_BLOCKS = [
    (path, index) for path in (README, DROP_IN) for index in range(len(code_blocks("python", path)))
]


@pytest.mark.parametrize(
    ("path", "index"), PYTHON_BLOCKS, ids=[f"{p.name}:{i}" for p, i in PYTHON_BLOCKS]
)
def test_readme_python_block_runs_verbatim(path, index):
    torch.manual_seed(0)
    namespace = {"my_env": PressEnv()}
    block = code_blocks("python", path)[index]
    exec(compile(block, f"{path.name} block {index}", "exec"), namespace)
    for name, value in namespace.items():  # every rollout / batch it made has checked rewards
        if isinstance(value, TensorDictBase) and ("next", keys.PENALTY) in value.keys(True):
            force_key = FORCE if FORCE in value.keys() else keys.TOUCH
            force, next_force = value[force_key], value["next", force_key]
            expected = impact_penalty(impact(force, next_force), 2.0, 2.0).unsqueeze(-1)
            torch.testing.assert_close(value["next", keys.PENALTY], expected, msg=name)
            assert value["next", keys.IMPACT].shape == force.shape[:-1]
    if "rb" in namespace:  # the drop-in block: 20 updates, past its reward delay of 10
        assert namespace["rewards"].intrinsic_on and namespace["rewards"].num_updates == 20
        n = namespace["sample"]["next"]
        penalty, surprise = n[keys.PENALTY], n[keys.PENALTY_SURPRISE]
        torch.testing.assert_close(n[keys.REWARD], n[keys.TASK_REWARD] + penalty + surprise)
        assert (penalty < 0).any() and (surprise[penalty < 0] > 0).all()
        assert (surprise[penalty == 0] == 0).all()  # eq. 8: no penalty, no surprise


def readme_commands(path: Path = README) -> list[list[str]]:
    """``gentlerl ...`` command lines of ``path``: in bash blocks and in inline code."""
    text = path.read_text()
    blocks = code_blocks("bash", path)
    lines = [ln for block in blocks for ln in block.replace("&&", "\n").splitlines()]
    lines += re.findall(r"`(gentlerl(?:-train)? [^`]*)`", text)
    commands = [shlex.split(ln.split("#")[0]) for ln in lines]
    commands = [c for c in commands if c and c[0] in ("gentlerl", "gentlerl-train")]
    commands = [c for c in commands if c[1:2] != ["COMMAND"]]  # the placeholder in the prose
    return [["gentlerl", "train", *c[1:]] if c[0] == "gentlerl-train" else c for c in commands]


@pytest.mark.parametrize("path", PAGES, ids=[p.name for p in PAGES])
def test_readme_gentlerl_commands_name_real_subcommands_options_and_config_fields(path):
    commands = readme_commands(path)
    if path in (README, PAGES[2]):  # the quick start: the default recipe as it is
        assert ["gentlerl", "train"] in commands
    assert commands, f"{path.name} names no gentlerl command"
    fields = {name for name, _ in iter_fields()}
    for command in commands:
        assert command[1] in cli.COMMANDS, command
        if command[1] == "train":  # hydra overrides: every key is a config field
            overrides = [a for a in command[2:] if a not in ("KEY=VALUE", "...", "-m", "--help")]
            # "+" adds a key; a key inside the env.kwargs mapping names that field.
            names = {a.split("=")[0].lstrip("+") for a in overrides}
            names = {"env.kwargs" if n.startswith("env.kwargs.") else n for n in names}
            assert names <= fields, command
            continue
        module, _ = cli.COMMANDS[command[1]]
        build_parser = getattr(importlib.import_module(module), "build_parser", None)
        if build_parser is not None and command[2:]:  # argparse commands: every option exists
            _, unknown = build_parser().parse_known_args(command[2:])
            assert not unknown, command


def test_readme_finger_block_builds_a_float32_env_with_force_in_newtons():
    """The drop-in page's second example (once the README's), on the real
    ``DMControlEnv("finger", "spin")``: specs pass, every float entry is float32, force =
    expm1(touch) as [2 sites, 1 channel], and the flat observation is position, velocity, touch."""
    (block,) = [b for b in code_blocks("python", DROP_IN) if "DMControlEnv" in b]
    torch.manual_seed(0)
    namespace: dict = {}
    exec(compile(block, "torchrl.md finger block", "exec"), namespace)
    finger, rollout = namespace["finger"], namespace["rollout"]
    check_env_specs(finger)
    assert finger.observation_spec[FORCE].shape == (2, 1)
    assert rollout.shape == (300,) and rollout["next", keys.IMPACT].shape == (300, 2)
    floats = [v for v in rollout.values(True, True) if v.is_floating_point()]
    assert all(v.dtype == torch.float32 for v in floats)
    torch.testing.assert_close(
        rollout["next", FORCE][..., 0], torch.expm1(rollout["next", "touch"])
    )
    obs = torch.cat([rollout["position"], rollout["velocity"], rollout["touch"]], -1)
    torch.testing.assert_close(rollout[keys.OBSERVATION], obs)
    expected = impact_penalty(impact(rollout[FORCE], rollout["next", FORCE]), 2.0, 2.0)
    torch.testing.assert_close(rollout["next", keys.PENALTY], expected.unsqueeze(-1))


def test_the_first_screen_numbers_stand_in_the_files_they_cite():
    """The default recipe's numbers on the first screen are the dated ones of docs/RESULTS.md's
    "The README's numbers"; the hand's measured table is generated from the re-measure suite's
    CSV (its numbers are checked against the CSV by tests/repo/test_generated_tables.py)."""
    text = README.read_text()
    head = first_screen(text)
    sentence = re.search(r"\*\*What you get\*\*: (.*?)```", head, re.S)
    assert sentence, "the first screen's 'What you get' is gone"
    numbers = re.findall(r"\d+\.\d+", sentence[1])
    results = (ROOT / "docs" / "RESULTS.md").read_text()
    dated = results[results.index("## The README's numbers") :]
    dated = " ".join(dated[: dated.index("\n## ")].split())
    assert len(numbers) == 6, numbers  # 3 seeds, r's press, the shipped policy's success, impact
    assert all(n in dated for n in numbers), [n for n in numbers if n not in dated]
    suite_csv = "experiments/suites/after_fix/results.csv --tasks touch,fragile"
    assert f"<!-- generated by `gentlerl table {suite_csv}`" in text, "the hand's table is gone"


def test_the_readme_is_a_readme_not_a_lab_notebook():
    """About 150 lines and a short first screen: under 200 words of prose (outside code blocks
    and comments) and under 300 in all, room left for the pasted run (the README had 299 lines
    and a 652-word first screen); no research-log words on it."""
    text = README.read_text()
    assert len(text.splitlines()) <= 165
    screen = first_screen(text)
    prose = re.sub(r"<!--.*?-->", "", re.sub(r"^```.*?^```", "", screen, flags=re.M | re.S))
    assert len(prose.split()) < 200 and len(screen.split()) < 300
    assert "after the fix" not in text.lower() and "†" not in text
    assert not re.search(r"\b[0-9a-f]{7,40}\b", text), "a commit hash on the front page"
    log = (ROOT / "docs" / "log").resolve()  # the research log's folder
    links = [(ROOT / link).resolve() for link in re.findall(r"\]\(([^)#]+)", text)]
    assert sum(link.is_relative_to(log) for link in links) <= 2, "links into the research log"


def test_the_hand_table_states_the_suites_settings_not_the_defaults():
    """The table is the suite's (its random frames, curiosity delay and frames, from the suite
    file), and the README says so beside the defaults of the code."""
    import yaml

    from gentlerl.config import CollectorConfig, GentlenessConfig

    suite = yaml.safe_load((ROOT / "experiments" / "suites" / "after_fix.yaml").read_text())
    settings = dict(s.split("=") for s in suite["set"] + suite["tasks"]["touch"])
    stated = " ".join(README.read_text().split())
    suite_part = (
        f"({int(settings['collector.total_frames']) // 1000}k frames, "
        f"{int(settings['collector.init_random_frames']) // 1000}k random frames, "
        f"curiosity delay {int(settings['gentleness.reward_delay']):,})"
    )
    defaults = (
        f"({CollectorConfig().total_frames // 1000}k frames, "
        f"{CollectorConfig().init_random_frames // 1000}k random frames, "
        f"curiosity delay {GentlenessConfig().reward_delay:,})"
    )
    assert f"at its own settings {suite_part}, not the defaults {defaults}" in stated


def test_the_gpu_learner_rate_stands_in_the_benchmark_results():
    """The configuration page's paper-scale GPU rate is the one benchmarks/RESULTS.md measured."""
    page = (ROOT / "docs" / "site" / "configuration.md").read_text()
    match = re.search(r"\(([\d,]+) paper-scale updates/s on an H200", page)
    assert match, "the configuration page's GPU learner sentence is gone"
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    assert f"**{match.group(1)}" in results or f"{match.group(1)}–" in results


def test_the_first_screen_states_the_tasks_thresholds_of_the_code():
    """The touch task succeeds above force_threshold N; the fragile block breaks at an impact
    above break_impact N (the README once said 'at most 5 N' and 'above 5 N')."""
    import inspect

    from gentlerl.envs.hand import Fragile, Touch

    touch = inspect.signature(Touch.__init__).parameters["force_threshold"].default
    fragile = inspect.signature(Fragile.__init__).parameters["break_impact"].default
    text = " ".join(README.read_text().split())
    assert f"succeeds at a press on the block above {touch:g} N" in text
    assert f"breaks at an impact above {fragile:g} N" in text


def test_the_sac_recipe_diff_the_readme_states_is_the_recipes():
    """The README counts the recipe's marked lines and gentlerl imports."""
    code = (README.parent / "recipes" / "sac_gentle.py").read_text().splitlines()
    marked = sum(1 for line in code if "  # gentlerl" in line)  # inline comments only
    imports = sum(1 for line in code if line.startswith(("from gentlerl", "import gentlerl")))
    stated = f"{marked} lines marked `# gentlerl`, {imports} gentlerl imports"
    assert stated in " ".join(README.read_text().split())


def test_the_sac_recipe_imports_only_the_public_names_of_gentlerls_packages():
    """The recipe's gentlerl imports name packages (never a module inside one), and every name
    it imports is in that package's ``__all__``: what a TorchRL user may import too."""
    import ast
    import importlib

    tree = ast.parse((README.parent / "recipes" / "sac_gentle.py").read_text())
    imports = [
        node
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("gentlerl")
    ]
    assert imports
    for node in imports:
        assert node.module.count(".") == 1, f"{node.module} is a module inside a package"
        public = importlib.import_module(node.module).__all__
        assert {alias.name for alias in node.names} <= set(public), node.module


def test_the_tolerance_rule_the_readme_states_is_the_codes():
    """ "impacts in units of T/2, so T = 2 N is the paper's hand": the rule's lambda_2."""
    from gentlerl.functional import tolerance_unit
    from gentlerl.functional.constraint import PAPER_LAMBDA_2

    text = " ".join(README.read_text().split())
    assert (
        f"impacts in units of T/{PAPER_LAMBDA_2:g}, so T = {PAPER_LAMBDA_2:g} N is the paper's hand"
        in text
    )
    assert tolerance_unit(PAPER_LAMBDA_2) == 1.0  # the hand's newtons, unscaled


def test_which_gentleness_numbers_stand_in_the_results():
    """Every decimal number of the README's "Which gentleness to use" table is in docs/RESULTS.md
    (the Method IV tables there are generated from their CSVs: tests/repo/test_generated_tables.py)."""
    text = README.read_text()
    section = text[text.index("## Which gentleness to use") :]
    section = section[: section.index("\n## ", 1)]
    numbers = re.findall(r"\d+\.\d+", section)
    assert numbers, "the section states no measured number"
    results = (README.parent / "docs" / "RESULTS.md").read_text()
    assert [n for n in numbers if n not in results] == []
