"""The simulator's ROS parameters (pure: no rclpy; picking_common.params declares them)."""

from picking_common.params import Param
from picking_core.pick_cycle import GRIPPER_OPEN, HOME_POSITIONS

#: The pick cycle's home with the gripper open: where the default arm starts (another arm: every joint at 0).
HOME = [*HOME_POSITIONS, GRIPPER_OPEN]

PARAMS = (
    Param('urdf_path', '', "the arm's URDF file; empty: picking_description/urdf/picking_arm.urdf", read_only=True),
    Param('frame_prefix', '', 'prefix of this arm\'s frames on /tf (an arm in a namespace: "arm1/"): a scene in another '
          'frame is placed through /tf', read_only=True),
    Param('publish_rate', 100.0, 'rate of joint_states', 'Hz', (1.0, 10000.0), read_only=True),
    Param('servo_rate', 1000.0, 'rate of the position loop of Fig. 1 (at least publish_rate)', 'Hz',
          (10.0, 100000.0), read_only=True),
    Param('noise_std', 0.0, 'standard deviation of the Gaussian noise added to the joint_states positions', 'rad',
          (0.0, 1.0)),
    Param('command_timeout', 0.05, 'time without joint_commands after which the reference stops moving', 's',
          (0.001, 10.0), read_only=True),
    Param('thread_priority', 49, 'SCHED_FIFO priority of the servo thread (needs CAP_SYS_NICE or ulimit -r, else a '
          'warning); 0: normal scheduling', '', (0, 99), read_only=True),
    Param('loop_phase', -1.0, "-1: the servo's steps count from its start; 0 to < 1: at this fraction of a period past "
          'whole periods of the monotonic clock (several arms on one machine)', '', (-1.0, 1.0), read_only=True),
    Param('initial_positions', HOME, "the joints' positions at start, one per joint (the gripper's opening in m): "
          "the pick cycle's home with the gripper open (an arm with other joints: every joint at 0)", 'rad',
          read_only=True),
    Param('servo.bandwidth', 25.0, 'closed-loop natural frequency of the position loop', 'Hz', (0.1, 1000.0),
          read_only=True),
    Param('servo.damping', 1.0, 'damping ratio of the position loop', '', (0.01, 10.0), read_only=True),
    Param('servo.integral', 2.0, 'integral gain relative to the proportional gain', '1/s', (0.0, 100.0),
          read_only=True),
    Param('servo.inertia', 0.5, 'inertia each motor sees', 'kg m^2', (0.0001, 1000.0), read_only=True),
    Param('servo.friction', 0.8, 'viscous friction', 'N m s/rad', (0.0, 1000.0), read_only=True),
    Param('servo.max_torque', 400.0, 'motor torque saturation', 'N m', (0.1, 100000.0), read_only=True),
    Param('servo.velocity_margin', 1.2, 'the drive saturates at this times the URDF velocity limit (plans use up to '
          '1x)', '', (1.0, 10.0), read_only=True),
    Param('tree', '', "the apples the simulator hangs: 'orchard N SEED' (a tree among branches, its branches added to "
          "the scene), 'synthetic N SEED', a YAML file of 'apples: [[x, y, z], ...]' (m, base frame); empty: none",
          read_only=True),
    Param('fruit_seed', 0, "seed of the apples' diameters (6 to 8.5 cm) and stems (3 to 6 cm)", '', (0, 2 ** 31 - 1),
          read_only=True),
    Param('wind.amplitude', 0.0, 'the sway: horizontal push on each apple at its peak', 'm/s^2', (0.0, 100.0),
          read_only=True),
    Param('wind.frequency', 0.5, 'the sway\'s frequency', 'Hz', (0.0, 20.0), read_only=True),
    Param('wind.direction', 0.0, 'where the wind blows to, about z from x', 'rad', (-7.0, 7.0), read_only=True),
    Param('wind.gust_rate', 0.0, 'gusts a second, on average (each within 45 degrees of the wind)', '1/s', (0.0, 10.0),
          read_only=True),
    Param('wind.gust_strength', 0.0, "a gust's push at its peak", 'm/s^2', (0.0, 100.0), read_only=True),
    Param('wind.seed', 0, "seed of the apples' phases and the gusts", '', (0, 2 ** 31 - 1), read_only=True),
    Param('camera.enabled', True, 'the depth camera reports detections of the apples (with a tree)', read_only=True),
    Param('camera.frame', 'camera_optical_frame', "the camera's optical frame (z forward, x right, y down), on "
          "/tf_static under the arm's base, prefixed with frame_prefix", read_only=True),
    Param('camera.position', [0.1, 0.6, 1.3], "the camera's position", 'm', read_only=True),
    Param('camera.look_at', [0.68, 0.0, 0.62], 'the point it looks at', 'm', read_only=True),
    Param('camera.rate', 30.0, 'frames a second', 'Hz', (0.1, 1000.0), read_only=True),
    Param('camera.latency', 0.05, 'from capture (the stamp) to publication', 's', (0.0, 5.0), read_only=True),
    Param('camera.noise', 0.003, 'standard deviation of each coordinate of a detected centre', 'm', (0.0, 1.0),
          read_only=True),
    Param('camera.false_positives', 0.0, 'false detections a frame, on average', '', (0.0, 1000.0), read_only=True),
    Param('camera.occlusion', True, 'apples hidden by a branch, the arm or another apple are not seen', read_only=True),
    Param('camera.seed', 0, "seed of the camera's noise and false positives", '', (0, 2 ** 31 - 1), read_only=True),
    Param('scene_file', '', 'the obstacles the simulator watches the arm against, as the planner\'s scene_file (empty: '
          'the shipped picking_description/scenes/workcell_scene.yaml); the scene topic replaces it', read_only=True),
)

#: picking-state-publisher's parameters (state_publisher.py).
STATE_PUBLISHER = (
    Param('urdf_path', '', "the arm's URDF file; empty: picking_description/urdf/picking_arm.urdf", read_only=True),
    Param('frame_prefix', '', 'prefix of every link frame of this arm (an arm in a namespace: "arm1/"), as '
          "robot_state_publisher's frame_prefix", read_only=True),
    Param('parent_frame', '', 'the frame the arm stands in (a platform): its base is published in it as a static '
          'transform; empty: the base is a root of the tree', read_only=True),
    Param('parent_xyz', [0.0, 0.0, 0.0], 'where the arm\'s base is in parent_frame', 'm', read_only=True),
    Param('parent_rpy', [0.0, 0.0, 0.0], 'how the arm\'s base is turned in parent_frame: roll, pitch, yaw', 'rad',
          read_only=True),
    Param('update_rate', 20.0, 'how often the joint states received are turned into /tf: every one of them is '
          'published, stamped with its state (a wake per message would cost the process far more)', 'Hz',
          (1.0, 1000.0), read_only=True),
)
