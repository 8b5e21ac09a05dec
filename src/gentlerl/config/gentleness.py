"""The gentleness settings: the paper's lambdas, its models and schedule, and Method III's
tolerance, normalised curiosity and impact multiplier."""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field

from gentlerl.config.fields import setting
from gentlerl.config.limits import (
    MAX_BATCH,
    MAX_FORCE,
    MAX_FRAMES,
    MAX_GAIN,
    MAX_HANDS,
    MAX_TRANSITIONS,
    MAX_WEIGHT,
    MAX_WIDTH,
    MIN_FORCE,
)

#: gentleness.multiplier: the penalty head's weight fixed at 1 (the paper), steered by a PID
#: Lagrange multiplier toward the tolerance (Method III), or Method IV's Lagrangian: the episodes'
#: cost above the tolerance held under ``cost_limit`` (:class:`gentlerl.rewards.CostLagrangian`).
MULTIPLIERS = ("none", "pid", "lagrangian")


@dataclass
class GentlenessConfig:
    lam: tuple[float, float] = setting(
        (2.0, 2.0), "impact acceptability [lambda_1, lambda_2] (eq. 3)"
    )
    lam_prime: tuple[float, float] = setting(
        (2.0, 2.0), "penalty-surprise gate [l'_1, l'_2] (eq. 8)"
    )
    reward_delay: int = setting(
        2_000, "model updates before the curiosity rewards switch on", bounds=">= 0",
        resumable=True,
    )  # fmt: skip
    dynamics_target_period: int = setting(
        500, "model updates between dynamics target copies", bounds=">= 1", resumable=True
    )
    penalty_target_period: int = setting(
        100, "model updates between penalty target copies", bounds=">= 1", resumable=True
    )
    ensemble_size: int = setting(5, "members of each model ensemble", bounds="[1, 32]")
    model_hidden: int = setting(
        128, "units of each of the models' 3 hidden layers", bounds=f"[1, {MAX_WIDTH // 2}]"
    )
    model_batch_size: int = setting(
        64, "transitions per ensemble member and model update", bounds=f"[1, {MAX_BATCH}]",
        resumable=True,
    )  # fmt: skip
    model_buffer_size: int = setting(
        100_000, "1-step transitions kept for the models", bounds=f"[1, {MAX_TRANSITIONS}]"
    )
    lr_model: float = setting(1e-3, "Adam step size of the models", bounds="> 0", resumable=True)
    surprise_scale: float = setting(
        1.0,
        "multiplies r^s and the NLL inside r^sp (not its refund of r^f)",
        bounds=f"[0, {MAX_WEIGHT}]",
    )
    # r^s (eq. 6) is an NLL summed over 63 state dimensions: measured at CPU scale (touch, r+rf+rs)
    # 7-54 per step after the switch, so its non-episodic critic (value ~ r / (1 - gamma)) sat at
    # the support's +10 top. 1/500 maps the largest measured r^s to ~10.
    dynamics_surprise_scale: float = setting(
        0.002,
        "extra factor on the dynamics surprise r^s",
        bounds=f"[0, {MAX_WEIGHT}]",
        ablation=True,
    )
    # Measured: with supports per head and r^sp
    # recomputed at sampling, the fragile probe ended at 1.00 without a floor and 0.85 with 0;
    # the NLL of contact steps stayed near +1 at 30k frames either way.
    surprise_nll_floor: float | None = setting(
        None, "floor of the penalty-surprise NLL (null: eq. 8)", ablation=True
    )
    surprise_kind: str = setting(
        "nll",
        "what r^sp's curiosity reads: nll (eq. 8) or information_gain (the penalty ensemble's "
        "disagreement, which fades as it learns)",
        choices=("nll", "information_gain"),
        ablation=True,
    )
    rescore_surprise: bool = setting(
        True,
        "recompute r^sp of each sampled n-step transition with the current target model",
        ablation=True,
    )
    #: ``rescore_surprise``'s earlier name: a keyword that warns and sets it, until 0.3.0 (not a
    #: field: configs and checkpoints hold ``rescore_surprise`` only).
    recompute_surprise: InitVar[bool | None] = field(default=None, kw_only=True)

    def __post_init__(self, recompute_surprise: bool | None) -> None:
        if recompute_surprise is not None:
            from gentlerl.deprecation import warn_deprecated  # config imports no other gentlerl

            warn_deprecated(
                "GentlenessConfig(recompute_surprise=...)",
                "GentlenessConfig(rescore_surprise=...)",
                stacklevel=4,  # the caller of the dataclass's __init__
            )
            self.rescore_surprise = recompute_surprise

    icm_eta: float = setting(1.0, "scale eta of the ICM reward", bounds=f"[0, {MAX_WEIGHT}]")
    # Method III (beyond the paper): one stated tolerance, no per-env tuning.
    tolerance: float | None = setting(
        None,
        "the impact one step may deal, in the unit the rewards read (N): the penalty reads impacts "
        "in units of tolerance / 2, so lam and lam_prime keep the paper's values on every env "
        "(null: impacts in N, the paper)",
        bounds=f"[{MIN_FORCE}, {MAX_FORCE}]",
    )
    curiosity_norm: bool = setting(
        False,
        "divide r^sp's curiosity by its running mean magnitude on contact steps (about 1 per "
        "contact step on every env)",
    )
    multiplier: str = setting(
        "none",
        "the penalty head's weight in the actor's objective: none (1, the paper) or pid (1 + a PID "
        "Lagrange multiplier holding the episodes' max impact at the tolerance)",
        choices=MULTIPLIERS,
    )
    multiplier_gains: tuple[float, float, float] = setting(
        (1.0, 0.1, 0.0),
        "PID gains [K_P, K_I, K_D] of multiplier=pid (error: doublings above the tolerance)",
        bounds=f"[0, {MAX_GAIN}]",
    )  # fmt: skip
    multiplier_period: int | None = setting(
        None,
        "env steps between the multiplier's PID steps (null: one step per finished episode)",
        bounds=f"[1, {MAX_FRAMES}]",
    )
    multiplier_integral_max: float | None = setting(
        None,
        "cap of the multiplier's PID integral (anti-windup; null: none)",
        bounds=f"[0, {MAX_WEIGHT}]",
    )
    multiplier_base: float = setting(
        1.0,
        "w = multiplier_base + mu: 1 keeps at least the paper's weight, 0 is a plain Lagrangian "
        "(no penalty while the impacts stay within the tolerance)",
        bounds=f"[0, {MAX_WEIGHT}]",
    )
    multiplier_episodes: int = setting(
        0,
        "noise-free episodes of the current actor run at each PID step, whose max impacts are "
        "the cost (the deployed policy; needs multiplier_period; 0: the collection episodes)",
        bounds=f"[0, {MAX_HANDS}]",
    )
    # Method IV: the constrained problem as safe RL writes it (gentlerl.rewards.lagrangian).
    cost_limit: float = setting(
        25.0,
        "multiplier=lagrangian: the episodes' mean cost allowed, in steps of violation (a step's "
        "cost is its impact above the tolerance in tolerances, capped at 1; Safety Gym: 25 per "
        "1000 steps)",
        bounds=f"(0, {MAX_FRAMES}]",
    )
    cost_gains: tuple[float, float, float] = setting(
        (1.0, 0.1, 0.0),
        "multiplier=lagrangian: PID gains [K_P, K_I, K_D] on the mean episode cost in limits "
        "minus 1 (J / cost_limit - 1: one set of gains for every limit)",
        bounds=f"[0, {MAX_GAIN}]",
    )
    cost_warmup_frames: int = setting(
        0,
        "multiplier=lagrangian: env steps before the multiplier moves (the critics learn first)",
        bounds=f"[0, {MAX_FRAMES}]",
    )
    cost_period: int = setting(
        1000,
        "multiplier=lagrangian: env steps between the multiplier's PID steps (half OmniSafe's "
        "2000-step epoch)",
        bounds=f"[1, {MAX_FRAMES}]",
    )
    cost_multiplier_max: float = setting(
        100.0,
        "multiplier=lagrangian: cap of the multiplier's PID integral (OmniSafe's penalty_max)",
        bounds=f"[0, {MAX_WEIGHT}]",
    )
