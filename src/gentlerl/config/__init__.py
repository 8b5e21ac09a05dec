"""The contracts every layer shares, at the bottom of the package: the settings of a run (one
declaration per field) and the layout of a run directory. Imports nothing else of gentlerl."""

from gentlerl.config.fields import (
    Range,
    declared_problems,
    get,
    iter_fields,
    resumable,
    setting,
    type_problems,
)
from gentlerl.config.groups import (
    AUTO_NUM_ENVS,
    COLLECTORS,
    GROUPS,
    LOGGERS,
    WANDB_MODES,
    CollectorConfig,
    EnvConfig,
    GentlenessConfig,
    LearnerConfig,
    LoggingConfig,
    NetworkConfig,
    ReplayConfig,
)
from gentlerl.config.presets import SCALES
from gentlerl.config.rules import GROUP_RULES, check_group

__all__ = [
    "AUTO_NUM_ENVS",
    "COLLECTORS",
    "GROUPS",
    "GROUP_RULES",
    "LOGGERS",
    "SCALES",
    "WANDB_MODES",
    "check_group",
    "CollectorConfig",
    "EnvConfig",
    "GentlenessConfig",
    "LearnerConfig",
    "LoggingConfig",
    "NetworkConfig",
    "Range",
    "ReplayConfig",
    "declared_problems",
    "get",
    "iter_fields",
    "resumable",
    "setting",
    "type_problems",
]
