"""``gentlerl-train``: the hydra app that trains one run (``recipes/train.py`` runs the same app).

    gentlerl-train task=touch variant=r+rf+rsp seed=0
    gentlerl-train scale=paper replay.batch_size=64 gentleness.lam_prime=[2,3]
    gentlerl-train -m variant=r,r+rf+rsp seed=0,1,2     # a sweep, one run after the other
    gentlerl-train --help                               # every field, its default and choices

The config lives in the package (hydra's ``ConfigStore``): the schema is
:class:`~gentlerl.training.TrainConfig`, ``scale=<name>`` applies a preset of
:data:`~gentlerl.config.SCALES`, and every field is overridden as ``group.field=value``.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from gentlerl.config import SCALES
from gentlerl.config.fields import choices_of, get
from gentlerl.training.config import TrainConfig, iter_fields, make_config

#: Where a run goes unless ``run_dir=...`` is given (an external env's runs under its task name).
RUN_DIR = "runs/${gentlerl_run_name:${task},${env.name}}/${variant}/seed${seed}"


def run_name(task: str, env_name: str | None) -> str:
    """The first folder of a run's default directory: the hand's ``task``, or the task of an
    external env (``env.name=dm_control:finger-spin`` -> ``finger-spin``)."""
    return task if env_name is None else env_name.rpartition(":")[2]


HELP = """gentlerl-train: train a gentle-manipulation agent (Huang et al. 2019) with TorchRL.

Usage: gentlerl-train [field=value ...] [scale=cpu|paper|real] [-m sweep=a,b ...]
Example: gentlerl-train task=fragile variant=r+rf+rsp gentleness.lam_prime=[2,1.5] seed=1

Fields (default, then {choices}):
"""


def describe() -> str:
    """One line per field: ``name=default  help [choices]`` (what ``--help`` prints)."""
    defaults = TrainConfig()
    lines = []
    for name, f in iter_fields():
        choices = choices_of(f)
        valid = f"  {{{', '.join(map(str, choices))}}}" if choices else ""
        # The app's run_dir is an interpolation of the run's identity, not the dataclass default.
        shown = "runs/<task>/<variant>/seed<seed>" if name == "run_dir" else get(defaults, name)
        lines.append(f"  {name}={_override(shown)}".ljust(42) + f" {f.metadata['help']}{valid}")
    return "\n".join(lines)


def _override(value: Any) -> str:
    """``value`` as a hydra override writes it (``true``, ``null``, ``[2,3]``)."""
    if isinstance(value, bool):
        return str(value).lower()
    if value is None:
        return "null"
    if isinstance(value, list | tuple):
        return "[" + ",".join(_override(v) for v in value) + "]"
    return str(value)


def help_page() -> str:
    """What ``--help`` prints: the usage, one line per field, then hydra's own flags.

    Printed before hydra starts: hydra's help would first list every config group, which takes
    seconds, for a page that shows none of them.
    """
    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import get_args_parser

    flags = Hydra.format_args_help(get_args_parser())
    return f"{HELP}{describe()}\n\nHydra flags:\n{flags}\n"


def register_configs() -> None:
    """Store the schema, the scale presets and the primary config."""
    OmegaConf.register_new_resolver("gentlerl_run_name", run_name, replace=True)
    cs = ConfigStore.instance()
    cs.store(name="train_schema", node=TrainConfig)
    for name, preset in SCALES.items():
        cs.store(group="scale", name=name, node={"scale": name, **preset}, package="_global_")
    defaults: list[Any] = [
        "train_schema",
        {"scale": "cpu"},
        "_self_",
        {"override hydra/job_logging": "disabled"},
        {"override hydra/hydra_logging": "disabled"},
    ]
    hydra_settings = {
        "run": {"dir": "${run_dir}"},
        "sweep": {"dir": "runs", "subdir": RUN_DIR.removeprefix("runs/")},
        "output_subdir": None,
        "job": {"chdir": False},
    }
    node = {"defaults": defaults, "run_dir": RUN_DIR, "hydra": hydra_settings}
    cs.store(name="gentlerl_train", node=node)


def config_from_hydra(cfg: DictConfig) -> TrainConfig:
    """The validated :class:`TrainConfig` of a composed hydra config."""
    values = OmegaConf.to_container(cfg, resolve=True)
    return make_config(**values)


def train_in(output_dir: Path, cfg: DictConfig) -> dict[str, float]:
    """Train the run ``cfg`` describes; on failure, remove ``output_dir`` if it is still empty.

    hydra makes its output dir (the run_dir) before the config is checked, so a refused run
    would leave an empty directory behind.
    """
    try:
        config = config_from_hydra(cfg)  # a refused config answers before torch is imported
        from gentlerl.training.loop import train

        return train(config)
    except Exception:
        if output_dir.is_dir() and not any(output_dir.iterdir()):
            output_dir.rmdir()
        raise


def quiet_torchrl_info() -> None:
    """TorchRL's logger at WARNING, unless ``RL_LOGGING_LEVEL`` says otherwise: its INFO lines
    (each replay storage's size) would sit between the progress bar and the summary. TorchRL
    reads the variable when it is imported (here, and in collector processes)."""
    import os

    os.environ.setdefault("RL_LOGGING_LEVEL", "WARNING")


@hydra.main(config_path=None, config_name="gentlerl_train", version_base="1.3")
def _app(cfg: DictConfig) -> dict[str, float]:
    from hydra.core.hydra_config import HydraConfig

    from gentlerl.apps.errors import debugging, interrupted, one_line
    from gentlerl.distributed import ClusterError

    quiet_torchrl_info()
    try:
        summary = train_in(Path(HydraConfig.get().runtime.output_dir), cfg)
    except ClusterError as err:  # Ray missing or its cluster unreachable: one line says why
        raise SystemExit(str(err)) from None
    except Exception as err:  # noqa: BLE001 - a refusal is one line; GENTLERL_DEBUG=1: traceback
        if debugging():
            raise
        if interrupted(err):  # Ctrl-C that surfaced as another error inside a library
            raise KeyboardInterrupt from None
        raise SystemExit(f"gentlerl train: error: {one_line(err)}") from None
    from gentlerl.apps.closing import closing_text
    from gentlerl.training.logging import force_unit

    print(closing_text(summary, cfg.run_dir, force_unit(cfg.env.force_scale)))
    return summary


def unknown_fields(overrides: list[str]) -> list[str]:
    """The keys of plain ``key=value`` overrides that name no config field (hydra's own
    ``hydra.*``, ``+`` / ``~`` / ``++`` overrides and flags are left to hydra)."""
    valid = {name for name, _ in iter_fields()}
    keys = [
        a.partition("=")[0] for a in overrides if "=" in a and not a.startswith(("-", "+", "~"))
    ]
    return [k for k in keys if k not in valid and not k.startswith("hydra.") and k != "hydra"]


def main() -> None:
    """Entry point of ``gentlerl-train``: parses ``sys.argv`` as hydra overrides."""
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(help_page())
        return
    unknown = unknown_fields(sys.argv[1:])
    if unknown:
        raise SystemExit(
            f"gentlerl train: error: unknown config field(s) {unknown}: `gentlerl train --help` "
            "lists them (a task keyword goes in as +env.kwargs.NAME=VALUE)"
        )
    register_configs()
    _app()


if __name__ == "__main__":
    main()
