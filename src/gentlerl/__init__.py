"""gentlerl: gentle object manipulation with curiosity-driven deep RL, for TorchRL.

Importing it changes nothing in the process: :mod:`gentlerl.envs` chooses dm_control's OpenGL
backend when it is first imported (:func:`gentlerl.opengl.configure_gl`, before dm_control), and
a training run's process set-up records a missing pandas
(:func:`gentlerl.training.builders.prepare_process`).
"""

__version__ = "0.1.0"
