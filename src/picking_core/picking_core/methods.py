"""The names of the planner's methods (light: a command-line tool checks a user's choice without loading the core)."""

#: Joint-space moves to a pose: the paper's profiles, and Ruckig's jerk-limited time-optimal move.
JOINT_METHODS = ('cubic', 'quintic', 'lspb', 'optimal')
#: Moves to a pose: a joint move, or a straight tool line.
POSE_METHODS = JOINT_METHODS + ('line',)
#: Moves through poses: timed via points, straight lines pose to pose, or a 3-point arc.
PATH_METHODS = ('via_lspb', 'quintic_via', 'optimal', 'line', 'arc')
