"""Pure functions for the paper's equations, one each, named as the paper's quantities."""

from gentlerl.functional.constraint import (
    excess_cost,
    lagrangian_weights,
    normalized_curiosity,
    normalized_values,
    overshoot,
    pid_lagrangian,
    running_mean_update,
    tolerance_unit,
)
from gentlerl.functional.distributional import categorical_projection, categorical_support
from gentlerl.functional.gentleness import (
    acceptability,
    force_penalty,
    gaussian_nll,
    gaussian_nll_parts,
    impact,
    impact_penalty,
    information_gain,
    mixture_moments,
    penalty_surprise,
    torque_penalty,
)

__all__ = [
    "acceptability",
    "categorical_projection",
    "categorical_support",
    "excess_cost",
    "force_penalty",
    "gaussian_nll",
    "gaussian_nll_parts",
    "impact",
    "impact_penalty",
    "information_gain",
    "lagrangian_weights",
    "mixture_moments",
    "normalized_curiosity",
    "normalized_values",
    "overshoot",
    "penalty_surprise",
    "pid_lagrangian",
    "running_mean_update",
    "tolerance_unit",
    "torque_penalty",
]
