"""Pure functions for the paper's equations (see ``../shared/STYLE.md`` for the name map)."""

from gentlerl.functional.distributional import categorical_projection, categorical_support
from gentlerl.functional.gentleness import (
    acceptability,
    gaussian_nll,
    impact,
    impact_penalty,
    mixture_moments,
    penalty_surprise,
)

__all__ = [
    "acceptability",
    "categorical_projection",
    "categorical_support",
    "gaussian_nll",
    "impact",
    "impact_penalty",
    "mixture_moments",
    "penalty_surprise",
]
