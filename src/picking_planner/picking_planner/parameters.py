"""The planner's ROS parameters (pure: no rclpy; picking_common.params declares them).

The defaults are the library's (:class:`~picking_core.planning.PlannerSettings`,
:class:`~picking_core.pick_cycle.PickSettings`) but where :data:`NODE_DEFAULTS` says otherwise.
Every one but ``urdf_path`` takes effect at run time, checked with the others (a set that the
planner cannot plan with is refused with the reason).
"""

from picking_common.params import Param
from picking_core.collision import CLEARANCE as COLLISION_CLEARANCE
from picking_core.pick_cycle import PickSettings
from picking_core.planning import PlannerSettings
from picking_core.platform import CLEARANCE, SLACK

#: Where the node's defaults differ from the library's (the paper's methods): the jerk-limited,
#: blended motion a machine should run (config/paper_methods.yaml restores the paper's).
NODE_DEFAULTS = dict(method='optimal', path_method='optimal', cartesian_profile='optimal', limit_jerk=True,
                     approach_method='optimal', transfer_method='optimal', blend=True, blend_radius=0.02,
                     box_blend_radius=0.10, release_lead=0.2, speed_scale=1.0, point_period=0.1)

#: The parameters of the planning core (PlannerSettings) and of the pick cycle (PickSettings).
SETTINGS = ('method', 'path_method', 'speed_scale', 'duration', 'sample_period', 'point_period', 'cartesian_speed',
            'cartesian_accel', 'cartesian_profile', 'max_joint_step', 'limit_jerk')
PICK = ('approach_distance', 'lift_height', 'lift_method', 'approach_method', 'grasp_time', 'release_time',
        'box_position', 'box_drop_height', 'home_positions', 'transfer_method', 'transfer_lift',
        'place_orientation_rpy', 'place_yaw_free', 'gripper_open', 'gripper_closed', 'blend', 'blend_radius',
        'box_blend_radius', 'approach_cone', 'apple_region', 'apple_pass_speed', 'hold_time', 'release_lead')
#: The world the plans keep clear of (collision.World).
COLLISION = ('scene_file', 'avoid_collisions', 'collision_clearance')


def _default(name):
    if name in NODE_DEFAULTS:
        return NODE_DEFAULTS[name]
    value = getattr(PlannerSettings() if name in SETTINGS else PickSettings(), name)
    return [float(v) for v in value] if isinstance(value, tuple) else value


_TEXT = {
    'method': ('pose goals: cubic, quintic, lspb, optimal (joint space; optimal is jerk-limited and time-optimal) or '
               'line (Cartesian)', '', None),
    'path_method': ('path goals: via_lspb, quintic_via, optimal, line or arc', '', None),
    'speed_scale': ('fraction of the joint velocity limits the plans use (accelerations: its square, jerks: its '
                    'cube)', '', (0.01, 1.0)),
    'duration': ('duration of a pose move; 0: the shortest within the limits', 's', (0.0, 3600.0)),
    'sample_period': ('spacing of the samples a plan is made and checked at: a line\'s or arc\'s IK, the shortest '
                      'segment (the paper samples every 0.01 s)', 's', (0.001, 1.0)),
    'point_period': ('longest time between two points of a plan as it is sent; every break of the plan is a point too, '
                     'so the controller runs it exactly', 's', (0.001, 10.0)),
    'cartesian_speed': ('first guess of the tool speed on lines and arcs (stretched to the joint limits)', 'm/s',
                        (0.001, 10.0)),
    'cartesian_accel': ('tool acceleration on lines and arcs', 'm/s^2', (0.001, 100.0)),
    'cartesian_profile': ('progress along lines and arcs: quintic, lspb, cubic or optimal (jerk-limited, '
                          'time-optimal)', '', None),
    'max_joint_step': ('largest joint change between two samples of a Cartesian path; a larger one (an IK branch '
                       'flip) refuses the path', 'rad', (0.001, 3.2)),
    'limit_jerk': ('keep the jerk limits too: lines, arcs and quintics stretched, cubic and LSPB moves refused', '',
                   None),
    'approach_distance': ('P1 lies this far back from the apple along the tool z axis', 'm', (0.001, 1.0)),
    'lift_height': ('P3 lies this far above the apple (lift_method back: this far back from it)', 'm', (0.001, 1.0)),
    'lift_method': ('the lift: line (straight up), arc (up and back along a quarter arc) or back (straight back '
                    'along the approach); a blocked apple tries the others', '', None),
    'approach_method': ('joint-space moves to P0 and P1: lspb, quintic, cubic or optimal', '', None),
    'grasp_time': ('dwell while the gripper closes', 's', (0.001, 60.0)),
    'release_time': ('dwell while the gripper opens', 's', (0.001, 60.0)),
    'release_lead': ('the fingers begin to open this long before the tool reaches P5, on the line into the box (at '
                     'most that line): the dwell at P5 is that much shorter; 0: the whole release at P5', 's',
                     (0.0, 60.0)),
    'box_position': ('P5, the drop point in the fruit box (x, y, z in base_link)', 'm', None),
    'box_drop_height': ('P4 lies this far above P5', 'm', (0.001, 2.0)),
    'home_positions': ("P0, the arm's home, one value per arm joint (the simulator starts there)", 'rad', None),
    'transfer_method': ('the transfer to the box and the return: via_lspb, quintic_via or optimal', '', None),
    'transfer_lift': ("the transfer's via point is the joint-space midpoint with the shoulder lifted back by this",
                      'rad', (0.0, 0.999)),
    'place_orientation_rpy': ('tool orientation over the box, roll, pitch, yaw', 'rad', None),
    'place_yaw_free': ('the planner may turn the gripper about the vertical over the box (the quickest turn)', '',
                       None),
    'gripper_open': ('finger opening of the open gripper', 'm', (0.0, 1.0)),
    'gripper_closed': ('finger opening closed on an apple', 'm', (0.0, 1.0)),
    'blend': ('pass P1, P3 and P4 at speed (needs approach and transfer methods optimal and cartesian_profile '
              'optimal)', '', None),
    'blend_radius': ('with blend: the joint moves meet the lines this far from P1 and P3, rounding the corners '
                     '(less than half of each line at the apple)', 'm', (0.0, 0.5)),
    'box_blend_radius': ('with blend: the transfer meets the line into the box, and the rise out of it the next move, '
                         'this far below P4 (less than box_drop_height)', 'm', (0.0, 2.0)),
    'approach_cone': ('when the requested approach to an apple is blocked or out of reach, other grasp axes are tried '
                      'this far from it (0: none)', 'rad', (0.0, 1.5708)),
    'apple_region': ('radius around an apple where touching is allowed (the apple and its stem)', 'm', (0.0, 0.5)),
    'apple_pass_speed': ('in a harvest or a pick, the fastest a link may pass an apple still on the tree (the '
                         "harvest's others, the apples the camera sees): a joint move passing one faster, or pressing "
                         'one off its stem, goes around those apples where a way is found, else is slowed past them '
                         '(0: not looked at)', 'm/s',
                         (0.0, 10.0)),
    'hold_time': ('a pick of a moving apple whose closing is not sure waits at the stand-off at most this long from '
                  'its first hold, then backs off home without closing', 's', (0.1, 60.0)),
}

PARAMS = (
    Param('urdf_path', '', "the arm's URDF file; empty: picking_description/urdf/picking_arm.urdf", read_only=True),
    Param('joint_limits_path', '', "the arm's acceleration and jerk limits (MoveIt's joint_limits.yaml); empty: "
          '<URDF stem>_joint_limits.yaml beside the URDF, if there is one', read_only=True),
    Param('base_frame', 'base_link', "the URDF link the arm's chain starts at: goals, plans and the scene are in it",
          read_only=True),
    Param('tool_frame', '', "the URDF link that goes to a goal's pose (the grasp point); empty: tool0, else the "
          "chain's one tip", read_only=True),
    Param('controller_action', 'follow_joint_trajectory', "the arm controller's FollowJointTrajectory action (a "
          "ros2_controllers joint trajectory controller: '<controller>/follow_joint_trajectory')", read_only=True),
    Param('controller_state', '', "the arm controller's JointTrajectoryControllerState topic, where a plan from a "
          "moving arm reads its reference ('<controller>/controller_state'); empty: picking-controller's "
          'joint_commands', read_only=True),
    Param('gripper_action', '', 'a GripperCommand action for the gripper (gripper_action_controller: '
          "'<controller>/gripper_cmd'): trajectories then carry the arm's joints only and the gripper is commanded "
          'when a plan moves it; empty: the gripper is a joint of the trajectory (picking-controller)', read_only=True),
    Param('frame_prefix', '', 'prefix of this arm\'s frames on /tf (an arm in a namespace: "arm1/"): its base there is '
          '<frame_prefix><base frame>', read_only=True),
    Param('transform_timeout', 0.2, 'how long a goal, cloud or scene in another frame waits for its transform into the '
          'arm\'s base', 's', (0.0, 10.0)),
    Param('reference_timeout', 0.1, "plan from the controller's reference (joint_commands) while it is this fresh, "
          'else from joint_states', 's', (0.001, 10.0)),
    Param('grasp_check', True, "claim a pick's or a harvest's apple picked only when the gripper's measured opening shows that "
          'it held something while it carried the apple (its fingers stopped short of their closed opening); else '
          "the apple is missed, with why. false: claimed by the plan's clock (a gripper that reports no opening; "
          'picking-stack sets it so when its simulator hangs no apples)'),
    Param('start_delay', 0.1, 'a plan starts this long after its planning is expected to end (stamped so), so that a '
          'moving arm never jumps', 's', (0.0, 10.0)),
    *(Param(name, _default(name), text, unit, rng) for name, (text, unit, rng) in _TEXT.items()),
    Param('scene_file', '', 'the obstacles around the arm (YAML, see docs/collisions.md; empty: the shipped '
          'picking_description/scenes/workcell_scene.yaml); the scene topic replaces it at run time'),
    Param('avoid_collisions', True, 'check every plan against the scene, the canopy cloud and the arm itself, and '
          'pick around branches; false plans as if the world were empty'),
    Param('collision_clearance', COLLISION_CLEARANCE, 'the least distance kept between the arm and an obstacle', 'm',
          (0.0, 0.5)),
)

#: picking-harvester's parameters (the coordinator of several arms, harvester.py).
HARVESTER = (
    Param('platform_file', '', 'the platform: its arms\' namespaces, base poses and boxes (YAML; empty: the shipped '
          'picking_description/platforms/platform.yaml)', read_only=True),
    Param('layout', '', 'the layout of the platform file to run (empty: its default)', read_only=True),
    Param('clearance', CLEARANCE, 'the least distance kept between two arms\' collision capsules', 'm', (0.0, 1.0),
          read_only=True),
    Param('slack', SLACK, 'two arms\' plans are kept apart for a start of one this much before or after the other\'s',
          's', (0.0, 5.0), read_only=True),
)

