"""Train a gentlerl agent: ``python recipes/train.py task=touch variant=r+rf+rsp seed=0``.

The same hydra app as the ``gentlerl-train`` command (:mod:`gentlerl.apps.train`): every field
is overridden as ``group.field=value`` (``replay.batch_size=64``,
``gentleness.lam_prime=[2,3]``, ``logging.wandb_mode=online``, ``resume=true``), presets with
``scale=cpu|paper``; ``--help`` lists every field with its default and choices. A sweep:
``python recipes/train.py -m variant=r,r+rf+rsp seed=0,1,2``.

Everything a run writes goes to ``run_dir`` (default ``runs/<task>/<variant>/seed<seed>``).
"""

from gentlerl.apps.train import main

if __name__ == "__main__":
    main()
