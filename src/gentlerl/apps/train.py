"""``gentlerl-train``: the hydra app that trains one run (``gentlerl train`` runs the same app).

    gentlerl-train task=touch variant=r+rf+rsp seed=0
    gentlerl-train scale=paper replay.batch_size=64 gentleness.lam_prime=[2,3]
    gentlerl-train -m variant=r,r+rf+rsp seed=0,1,2     # a sweep, one run after the other
    gentlerl-train --help                               # every field, its default and choices

The config lives in the package (hydra's ``ConfigStore``): the schema is
:class:`~gentlerl.training.TrainConfig`, ``scale=<name>`` applies a preset of
:data:`~gentlerl.config.SCALES`, and every field is overridden as ``group.field=value``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from typing import Any

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

Fields (default, then {choices} or the range of its numbers):
"""


def describe() -> str:
    """One line per field: ``name=default  help [choices or range]`` (what ``--help`` prints)."""
    defaults = TrainConfig()
    lines = []
    for name, f in iter_fields():
        choices, bounds = choices_of(f), f.metadata["bounds"]
        valid = f"  {{{', '.join(map(str, choices))}}}" if choices else ""
        valid += f"  ({bounds.describe()})" if bounds is not None else ""
        # The app's run_dir is an interpolation of the run's identity, not the dataclass default.
        shown = "runs/<task>/<variant>/seed<seed>" if name == "run_dir" else get(defaults, name)
        mark = "[ablation] " if f.metadata.get("ablation") else ""
        lines.append(
            f"  {name}={_override(shown)}".ljust(42) + f" {mark}{f.metadata['help']}{valid}"
        )
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
        # The trainer makes run_dir once the config is checked; hydra makes nothing.
        "run": {"dir": "."},
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


def quiet_torchrl_info() -> None:
    """TorchRL's logger at WARNING, unless ``RL_LOGGING_LEVEL`` says otherwise: its INFO lines
    (each replay storage's size) would sit between the progress bar and the summary. TorchRL
    reads the variable when it is imported (here, and in collector processes)."""
    os.environ.setdefault("RL_LOGGING_LEVEL", "WARNING")


def _app(cfg: DictConfig, overrides: Sequence[str]) -> dict[str, float]:
    """Train the run of the composed config ``cfg`` (hydra's task; ``overrides``: the command
    line it came from, which a refusal quotes)."""
    from omegaconf.errors import OmegaConfBaseException

    from gentlerl.apps.errors import debugging, interrupted, one_line, sigterm_as_interrupt
    from gentlerl.apps.overrides import hydra_error_line
    from gentlerl.distributed import ClusterError

    quiet_torchrl_info()
    try:
        with sigterm_as_interrupt():  # SIGTERM stops a run as Ctrl-C does
            config = config_from_hydra(cfg)  # a refused config answers before torch is imported
            from gentlerl.training.loop import train

            summary = train(config)
    except ClusterError as err:  # Ray missing or its cluster unreachable: one line says why
        refusal = str(err)
    except Exception as err:  # noqa: BLE001 - a refusal is one line; GENTLERL_DEBUG=1: traceback
        if debugging():
            raise
        interrupt = interrupted(err)
        if interrupt is not None:  # Ctrl-C that surfaced as another error inside a library
            raise interrupt from None
        if isinstance(err, OmegaConfBaseException):  # resolving an interpolation
            refusal = f"gentlerl train: error: {hydra_error_line(err, overrides)}"
        else:
            refusal = f"gentlerl train: error: {one_line(err)}"
    else:
        refusal = None
    if refusal is not None:  # raised here, holding no reference to the error and its frames
        raise SystemExit(refusal)
    from gentlerl.apps.closing import closing_text
    from gentlerl.training.logging import force_unit

    print(closing_text(summary, cfg.run_dir, force_unit(cfg.env.force_scale)))
    return summary


def run_hydra(argv: Sequence[str]) -> None:
    """What ``@hydra.main`` does with ``sys.argv``, with ``argv``: hydra's flags and overrides
    parsed by hydra's own parser, then a run, a ``-m`` sweep, ``--cfg`` or ``--info`` of the
    train task. (hydra's compose API has no sweeps and no run directories, so this is hydra's
    own runner, handed the command line instead of reading the process's.)"""
    from hydra import version
    from hydra._internal.utils import _run_hydra, get_args_parser

    version.setbase("1.3")
    parser = get_args_parser()
    _run_hydra(
        args=parser.parse_args(list(argv)),
        args_parser=parser,
        task_function=lambda cfg: _app(cfg, argv),
        config_path=None,
        config_name="gentlerl_train",
    )


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> None:
    """Entry point of ``gentlerl-train`` and ``gentlerl train``: parses ``argv`` (default
    ``sys.argv[1:]``) as hydra overrides. A refusal, an error of hydra's or an interruption is
    one line on stderr (``GENTLERL_DEBUG=1``: the traceback).

    ``prog`` names the program in hydra's ``--help`` and ``-sc`` lines, which hydra 1.3 reads
    from ``sys.argv[0]`` alone: that one entry is set meanwhile (the arguments are handed)."""
    name = sys.argv[0]
    sys.argv[0] = name if prog is None else prog
    try:
        _main(list(sys.argv[1:] if argv is None else argv))
    finally:
        sys.argv[0] = name


def _main(argv: list[str]) -> None:
    if {"-h", "--help"} & set(argv):
        print(help_page())
        return
    from gentlerl.apps.errors import debugging, exit_status
    from gentlerl.apps.overrides import hydra_error_line, override_problems

    problems = override_problems(argv)
    if problems:
        raise SystemExit(f"gentlerl train: error: {'; '.join(problems)}")
    register_configs()
    full_error = os.environ.get(_FULL_ERROR)
    os.environ[_FULL_ERROR] = "1"  # hydra raises its errors instead of printing them
    try:
        run_hydra(argv)
        refusal = None
    except Exception as err:  # noqa: BLE001 - hydra's errors (composing the config) are refusals
        if debugging():
            raise
        refusal = f"gentlerl train: error: {hydra_error_line(err, argv)}"
    except KeyboardInterrupt as interrupt:
        if debugging():
            raise
        print("gentlerl train: interrupted", file=sys.stderr)
        refusal = exit_status(interrupt)
    finally:
        if full_error is None:
            os.environ.pop(_FULL_ERROR, None)
        else:
            os.environ[_FULL_ERROR] = full_error
    if refusal is not None:  # raised here, holding no reference to the error and its frames
        raise SystemExit(refusal)


#: Set, hydra raises the errors of composing a config instead of printing several lines (hydra
#: reads it from the environment only, so it is set for the call and restored).
_FULL_ERROR = "HYDRA_FULL_ERROR"


if __name__ == "__main__":
    main()
