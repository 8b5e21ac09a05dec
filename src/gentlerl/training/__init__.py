"""Training: config, the shared loop (a runner of :mod:`gentlerl.agent`), checkpoints, logging.

Its names are imported on first use (:mod:`gentlerl.lazy`): reading the config imports no torch.
"""

from gentlerl.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "gentlerl.training.checkpoint": ("load_checkpoint", "load_policy", "save_checkpoint"),
        "gentlerl.training.config": ("TrainConfig", "make_config", "validate"),
        "gentlerl.training.evaluation": (
            "EVAL_SEED_OFFSET",
            "actor_episodes",
            "evaluate_actor",
            "make_eval_env",
            "summarize",
        ),
        "gentlerl.training.loop": ("Lockstep", "Trainer", "train"),
        "gentlerl.training.seed_group": ("SeedGroup", "train_seeds"),
    },
)
