"""The controller's ROS parameters (pure: no rclpy; picking_common.params declares them)."""

from picking_common.params import Param

#: The tolerances and the stall limit: they take effect at run time (for the goals that start after).
RUNTIME = ('path_tolerance', 'goal_tolerance', 'goal_time_tolerance', 'stopped_velocity_tolerance', 'state_timeout',
           'stall_limit')

PARAMS = (
    Param('urdf_path', '', "the arm's URDF file; empty: picking_description/urdf/picking_arm.urdf", read_only=True),
    Param('update_rate', 1000.0, 'rate of the control loop and of joint_commands', 'Hz', (1.0, 10000.0),
          read_only=True),
    Param('thread_priority', 50, 'SCHED_FIFO priority of the control loop thread, as ros2_control (needs '
          'CAP_SYS_NICE or ulimit -r, else a warning); 0: normal scheduling', '', (0, 99), read_only=True),
    Param('executor_priority', 0, 'SCHED_FIFO priority of the thread that takes trajectories, below '
          'thread_priority (several arms on one machine); 0: normal scheduling', '', (0, 98), read_only=True),
    Param('loop_phase', -1.0, "-1: the loop's deadlines count from its start; 0 to < 1: at this fraction of a period "
          'past whole periods of the monotonic clock (several arms on one machine)', '', (-1.0, 1.0), read_only=True),
    Param('action_monitor_rate', 20.0, 'rate of the follow_joint_trajectory feedback while a goal runs', 'Hz',
          (0.1, 1000.0), read_only=True),
    Param('path_tolerance', 0.1, 'largest |measured - reference| while moving, beyond it: hold and report (a goal '
          'may set its own)', 'rad', (0.0, 10.0)),
    Param('goal_tolerance', 0.005, 'largest |measured - goal| at the end of a trajectory', 'rad', (0.0, 1.0)),
    Param('goal_time_tolerance', 2.0, 'time after the end to get within goal_tolerance', 's', (0.0, 3600.0)),
    Param('stopped_velocity_tolerance', 0.02, 'largest joint speed that counts as at rest at the goal', 'rad/s',
          (0.0, 10.0)),
    Param('state_timeout', 0.5, 'time without joint_states after which the controller reports feedback lost and holds',
          's', (0.001, 60.0)),
    Param('stall_limit', 0.05, 'a tick this much later than the previous one (a stalled loop) delays the trajectory '
          "by the excess instead of jumping ahead; the drive's command timeout", 's', (0.001, 10.0)),
)
