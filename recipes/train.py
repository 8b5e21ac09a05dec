"""Train a gentlerl agent: ``python recipes/train.py task=touch variant=r+rf+rsp seed=0``.

Config: ``recipes/config/config.yaml`` (hydra). Groups: ``variant=<name>`` (one file per paper
variant: r, r+rf, r+rf+rs, r+rf+rsp, r+icm, rs, rf+rs, rf+rsp) and ``scale=cpu|paper``; every
field of :class:`gentlerl.training.TrainConfig` can be overridden (``batch_size=64``,
``lam_prime=[2,3]``, ``wandb_mode=online``, ``resume=true``). A sweep:
``python recipes/train.py -m variant=r,r+rf+rsp seed=0,1,2``.

Everything a run writes goes to ``run_dir`` (default ``runs/<task>/<variant>/seed<seed>``).
"""

from __future__ import annotations

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from gentlerl.training import TrainConfig, make_config, train

ConfigStore.instance().store(name="train_config", node=TrainConfig)


@hydra.main(config_path="config", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> dict[str, float]:
    values = OmegaConf.to_container(cfg, resolve=True)
    summary = train(make_config(**values))
    print(" ".join(f"{k}={v:.3f}" for k, v in summary.items()))
    return summary


if __name__ == "__main__":
    main()
