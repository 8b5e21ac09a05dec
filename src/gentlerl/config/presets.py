"""The scale presets of a run: group -> field -> value, applied under the user's overrides.

The one place for them: :func:`~gentlerl.training.config.make_config` applies them and the
``gentlerl-train`` app registers each as an option of its ``scale`` group. ``cpu`` is the
dataclass defaults (sized to learn touch on a 2-core CPU).
"""

from __future__ import annotations

from typing import Any

#: Presets (group -> field -> value), applied under user overrides by :func:`make_config`.
#: ``paper``: what Huang et al. 2019 (Experiments) give: batch 256, buffer 1M, lr 1e-4, 500k steps,
#: reward delay 20k, dynamics / penalty target periods 5k / 1k, actor 300-200, critics 400-300,
#: 101 atoms on [-100, 100], ensembles of 5 x (3 x 128). Not given by the paper (D4PG / Acme
#: defaults, the same at both scales): n-step 5, gamma 0.99, exploration sigma 0.3.
SCALES: dict[str, dict[str, Any]] = {
    "cpu": {},
    "paper": {
        "collector": {"total_frames": 500_000, "init_random_frames": 10_000},
        "replay": {"batch_size": 256, "buffer_size": 1_000_000},
        "learner": {
            "utd_ratio": 1.0,
            "lr_actor": 1e-4,
            "lr_critic": 1e-4,
            "episodic_intrinsic": True,  # the paper's D4PG cuts every head at termination
        },
        "network": {
            "actor_hidden": (300, 200),
            "critic_hidden": (400, 300),
            "v_min": -100.0,
            "v_max": 100.0,
            "bounded_support": False,
            "dense_reward_bound": None,  # one shared support for every head, as published
        },
        "gentleness": {
            "reward_delay": 20_000,
            "dynamics_target_period": 5_000,
            "penalty_target_period": 1_000,
            "model_batch_size": 256,
            "model_buffer_size": 1_000_000,
            "surprise_nll_floor": None,
            "rescore_surprise": False,  # stored at collection, as the paper's reading
            "dynamics_surprise_scale": 1.0,  # eq. 6 as written
        },
        "logging": {"eval_every_frames": 25_000, "checkpoint_every_frames": 50_000},
    },
}
#: ``real``: the paper's real-robot runs (Huang et al. 2019, "Real robot experiments"): the paper
#: scale with 25,000 steps, lr 1e-3 and the intrinsic rewards on after 8,000 steps. Not in the
#: paper: 2,500 random frames (10 % of the run) and an evaluation and a checkpoint every 2,500
#: frames (a hardware run can stop at any time).
SCALES["real"] = {
    **SCALES["paper"],
    "collector": {"total_frames": 25_000, "init_random_frames": 2_500},
    "learner": {**SCALES["paper"]["learner"], "lr_actor": 1e-3, "lr_critic": 1e-3},
    "gentleness": {**SCALES["paper"]["gentleness"], "reward_delay": 8_000},
    "logging": {"eval_every_frames": 2_500, "checkpoint_every_frames": 2_500},
}
