"""The hand tasks' names, importing nothing: what ``--help`` and the config checks list.

:data:`~gentlerl.envs.factory.TASK_CLASSES` maps the same names, in this order, to their classes
(a test checks that they agree); reading them there would import MuJoCo and dm_control.
"""

TASK_NAMES: tuple[str, ...] = ("explore", "touch", "fragile")

#: Task keywords renamed since runs were saved, old -> new: a saved config's are moved on load
#: (:func:`gentlerl.training.migration.group_flat_config`), one typed today is refused naming the new.
RENAMED_KWARGS: dict[str, str] = {"calibration": "regime"}
