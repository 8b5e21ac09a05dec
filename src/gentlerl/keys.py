"""Every tensordict key gentlerl reads or writes, in one place.

Transforms, losses and the training loop take these as defaults for their ``in_keys`` /
``out_keys`` / ``set_keys``; users remap them there instead of editing strings across modules.
"""

# Observations written by the hand environment (float32).
JOINT_POS = "joint_pos"  # [24] joint angles (rad)
JOINT_VEL = "joint_vel"  # [24] joint velocities (rad/s)
TOUCH = "touch"  # [5, 3] per fingertip, per channel: sum over the 4x4 grid of |force| (N)
TOUCH_GRID = "touch_grid"  # [5, 3, 4, 4] raw touch-grid readings (N)
ACTUATOR_FORCE = "actuator_force"  # [20] force of each position actuator (N m at the joints)
OBSERVATION = "observation"  # [63] flat state for actor / critic: joint_pos, joint_vel, touch
PIXELS = "pixels"
# Written by the driver-backed env (gentlerl.envs.DriverHandEnv) besides the keys above.
TACTILE = "tactile"  # [5, R] raw tactile channels as the driver reads them (sensor units)
BLOCK_FORCE = "block_force"  # [1] force on the block (N), when the driver measures it
WATCHDOG = "watchdog"  # [1] bool: the force watchdog ended the episode at this step
TACTILE_FORCE = "tactile_force"  # [5, R] TouchSensorMap's output as a transform (N)

ACTION = "action"
REWARD = "reward"  # task reward r_t, [1]
DONE = "done"
TERMINATED = "terminated"
TRUNCATED = "truncated"
SUCCESS = "success"  # [1] bool: the task's success condition was met at this step
BROKEN = "broken"  # [1] bool: fragile task, the block broke at this step

# Written by gentlerl.transforms.
IMPACT = "impact"  # [n_sites] m_t^i (N)
PENALTY = "penalty"  # [1] r^f_t
DYNAMICS_SURPRISE = "dynamics_surprise"  # [1] r^s_t
PENALTY_SURPRISE = "penalty_surprise"  # [1] r^{sp}_t
ICM_REWARD = "icm_reward"  # [1] ICM baseline reward
FORCE_PENALTY = "force_penalty"  # [1] r^F_t, total fingertip force penalty
TORQUE_PENALTY = "torque_penalty"  # [1] r^tau_t, actuator effort penalty
EXCESS_PENALTY = "excess_penalty"  # [1] -c_t, Method IV's cost: impact above the tolerance
TASK_REWARD = "task_reward"  # [1] the env's own reward, kept by SumRewards when it writes "reward"

# The dynamics model's three predicted feature groups (paper: one ensemble per group).
DYNAMICS_FEATURES = (JOINT_POS, JOINT_VEL, TOUCH)

# Written by the critics / D4PG loss.
STATE_ACTION_VALUE_LOGITS = "state_action_value_logits"  # [..., K, num_atoms]
STATE_ACTION_VALUE_ATOMS = "state_action_value_atoms"  # [..., K, num_atoms] each head's support
PRIORITY = "td_error"  # [...] priority for the prioritised sampler
NSTEP_TERMINATED = "nstep_terminated"  # terminated flag of an n-step window's last step
