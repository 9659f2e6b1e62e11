"""``picking-planner``: the planner node, a ROS shell around the planning core and the goal policy.

Serves the actions ``move_to_pose``, ``follow_path`` and ``pick`` (picking_interfaces), and takes
the same goals on the topics ``goal_pose`` (PoseStamped), ``goal_path`` (PoseArray) and
``pick_target`` (PoseStamped), and a tree's apples to harvest on ``harvest_targets`` (PoseArray);
subscribes ``joint_states`` and ``joint_commands`` (the controller's reference, so that a goal
mid-motion continues smoothly). Every plan runs through
the controller's ``follow_joint_trajectory`` action: a goal ends with the controller's result
(see lifecycle.py). Publishes each plan sent on ``planned_trajectory``, its tool path on
``planned_path``, and every goal's transitions on ``planner_status`` (accepted, executing,
then succeeded, aborted, superseded, canceled or refused, with the reason).

The method is the ``method`` parameter (pose goals) or ``path_method`` (path
goals), both settable at run time; ``picking-goal --method`` sets them for one
goal. Every parameter is validated when it is set.
"""

from __future__ import annotations

import threading
import time
from functools import partial

import numpy as np
from control_msgs.action import FollowJointTrajectory
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from nav_msgs.msg import Path
from picking_interfaces.action import FollowPath, MoveToPose, Pick
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionClient, ActionServer, GoalResponse
from rclpy.node import Node
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState, PointCloud2
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from picking_common.codec import Codec
from picking_common.params import declare, usage
from picking_common.joint_state import reorder
from picking_common.run import run_node
from picking_common.status import Diagnostics, Level
from picking_common.topics import BURST, LATCHED, NEWEST, RELIABLE, LatestMessage

from picking_core.collision import Scene, World
from .goal_flow import GoalFlow
from picking_core.goal_policy import GoalPolicy
from picking_core.kinematics import ArmModel
from picking_core.lifecycle import Lifecycle
from .parameters import COLLISION, PARAMS, PICK, SETTINGS
from picking_core.pick_cycle import PickSettings
from picking_core.planning import Planner, PlannerSettings
from picking_description import default_urdf, scene_path
from picking_common.scene_msgs import cloud_points, take_scene


class PlannerNode(GoalFlow, Node):
    """ROS interface of the planner: its parameters, the arm's state, and (in :class:`GoalFlow`) its goals."""

    def __init__(self, **kwargs):
        super().__init__('picking_planner', **kwargs)
        declare(self, PARAMS)
        self.arm = ArmModel.from_urdf(self.get_parameter('urdf_path').value or default_urdf())
        # The compiled IK and forward kinematics load now (a fraction of a second from
        # numba's cache), not on the first goal.
        if not self.arm.load_ik() and self.arm.solver != 'numeric':
            self.get_logger().warning('the compiled IK did not load (is numba installed?): IK runs '
                                      'the vectorised closed form (the same solutions, slower)')
        self.names = list(self.arm.joint_names)
        self.planner = Planner(self.arm, self._settings({}))
        self.pick = PickSettings(**{n: self.get_parameter(n).value for n in PICK}).validate(self.arm)
        p = {n: self.get_parameter(n).value for n in COLLISION}
        self.world = World(self.arm, self._scene_file(p['scene_file']), p['collision_clearance'],
                           p['avoid_collisions'])
        self.add_on_set_parameters_callback(self._on_parameters)

        # Times on the ROS clock count from here: as float seconds of the epoch they would resolve a
        # quarter of a microsecond, too coarse for the microsecond between a plan's step points.
        self._origin_ns = self.get_clock().now().nanoseconds - 1_000_000_000
        self.policy = GoalPolicy(self.arm, self.get_parameter('start_delay').value)
        self.create_timer(0.1, self._every_tenth)
        # Trajectories and tool paths are written straight to CDR bytes (much faster than the
        # message classes) where this middleware reads them back as the same messages.
        self.codec = Codec()
        self.messages = Codec(raw=False)          # action goals are messages
        self.lifecycle = Lifecycle()
        self.controller = ActionClient(self, FollowJointTrajectory, 'follow_joint_trajectory')
        self.pub_traj = self.create_publisher(JointTrajectory, 'planned_trajectory', RELIABLE)
        self.pub_path = self.create_publisher(Path, 'planned_path', RELIABLE)
        self.pub_status = self.create_publisher(DiagnosticStatus, 'planner_status', BURST)
        self.sub_pose = self.create_subscription(PoseStamped, 'goal_pose', self._on_goal_pose, BURST)
        self.sub_path = self.create_subscription(PoseArray, 'goal_path', self._on_goal_path, BURST)
        self.sub_pick = self.create_subscription(PoseStamped, 'pick_target', self._on_pick_target, BURST)
        self.sub_harvest = self.create_subscription(PoseArray, 'harvest_targets', self._on_harvest_targets, BURST)
        # The world: a scene replaced whole by a latched MarkerArray, and the canopy by each cloud, built
        # into its octree on a thread of its own (a camera's clouds never wait for a plan, nor a plan for them).
        self.sub_scene = self.create_subscription(MarkerArray, 'scene', self._on_scene, LATCHED)
        self.sub_canopy = self.create_subscription(PointCloud2, 'canopy_points', self._on_canopy, NEWEST)
        self._clouds = CloudBuilder(self)
        # A new canopy (built on its own thread) has the running plans checked again in the executor's.
        self._world_changed = self.create_guard_condition(self._recheck_running)
        self._harvests = {}           # goal key -> HarvestRun of the harvests sent and not ended, oldest first
        self.actions = [ActionServer(self, action, name, execute_callback=partial(self._execute, kind, plan),
                                     goal_callback=lambda _: GoalResponse.ACCEPT,
                                     cancel_callback=self._cancel)
                        for action, name, kind, plan in (
                            (MoveToPose, 'move_to_pose', 'pose', lambda g: self._plan_pose(g.pose, g.method)),
                            (FollowPath, 'follow_path', 'path', lambda g: self._plan_path(g.path, g.method)),
                            (Pick, 'pick', 'pick', lambda g: self._plan_pick(g.target)))]
        self._superseded = 0          # goals answered as superseded since the last log line
        self._superseded_logged = 0.0
        # The measured state and the controller's reference, taken when a goal comes: no
        # executor callbacks at their rates (rclpy spends about a millisecond on each).
        self.states = LatestMessage(self, JointState, 'joint_states', reader=self.codec.state_reader())
        self.commands = LatestMessage(self, JointState, 'joint_commands', reader=self.codec.state_reader())
        self.diagnostics = Diagnostics(self, self.arm.name, self._diagnose)
        self.get_logger().info(f'planning for {self.arm.name} ({self.arm.dof} joints, IK: {self.arm.solver}); '
                               f'method {self.planner.settings.method}, path_method '
                               f'{self.planner.settings.path_method}, speed_scale {self.planner.settings.speed_scale}; '
                               f'avoiding {self.world.words()}')

    def _scene_file(self, path):
        scene = Scene.from_yaml(path or scene_path('workcell'))
        if scene.frame != self.arm.base_frame:
            raise ValueError(f'scene_file {path!r} is in frame {scene.frame!r}, not the arm\'s base frame '
                             f'{self.arm.base_frame!r} (no TF here)')
        return scene

    def _on_scene(self, msg):
        scene = take_scene(msg, self.arm.base_frame, self.get_logger())
        if scene is None:
            return
        self.world.replace(scene=scene)
        self.get_logger().info(f'scene replaced from the scene topic: avoiding {self.world.words()}')
        self._recheck_running()

    def _on_canopy(self, msg):
        self._clouds.offer(msg)

    def destroy_node(self):
        self._clouds.stop()
        return super().destroy_node()

    # -- parameters -------------------------------------------------------------------
    def _settings(self, changes):
        values = {n: self.get_parameter(n).value for n in SETTINGS}
        values.update(changes)
        return PlannerSettings(**values).validate()

    def _on_parameters(self, params):
        changes = {p.name: p.value for p in params}
        try:
            if set(changes) & set(SETTINGS):
                planner = Planner(self.arm, self._settings({k: v for k, v in changes.items() if k in SETTINGS}))
            else:
                planner = self.planner
            if set(changes) & set(PICK):
                values = {n: self.get_parameter(n).value for n in PICK}
                values.update({k: v for k, v in changes.items() if k in PICK})
                pick = PickSettings(**values).validate(self.arm)
            else:
                pick = self.pick
            start_delay = float(changes.get('start_delay', self.policy.start_delay))
            if not start_delay >= 0.0:
                raise ValueError(f'start_delay must be >= 0 s, got {start_delay}')
            scene = self._scene_file(changes['scene_file']) if 'scene_file' in changes else None
        except (ValueError, TypeError, OSError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.planner, self.pick = planner, pick
        self.world.replace(scene=scene, clearance=changes.get('collision_clearance'),
                           enabled=changes.get('avoid_collisions'))
        self.policy.start_delay = start_delay
        return SetParametersResult(successful=True)

    # -- state ---------------------------------------------------------------------------
    def _now(self):
        return time.monotonic()

    def _ros_now(self):
        """The controller's clock (the ROS clock), s since :attr:`_origin_ns`."""
        return (self.get_clock().now().nanoseconds - self._origin_ns) * 1e-9

    def _clock_time(self, stamp):
        """A ROS stamp (builtin_interfaces/Time) on the clock of :meth:`_ros_now`."""
        return (stamp.sec * 1_000_000_000 + stamp.nanosec - self._origin_ns) * 1e-9

    def _stamp_ns(self, t):
        """A time of :meth:`_ros_now` as a stamp, ns."""
        return self._origin_ns + int(round(t * 1e9))

    def measured(self):
        """The newest valid joint_states: ``(q, gripper opening or None)``, or None before any."""
        msg = self.states.take()
        if msg is None:
            return None
        try:
            q = reorder(msg.name, msg.position, self.names, 'joint_states')
        except (ValueError, IndexError):
            return None
        if not np.all(np.isfinite(q)):
            return None
        gripper = None
        if 'gripper_joint' in msg.name:
            g = msg.position[list(msg.name).index('gripper_joint')]
            gripper = g if np.isfinite(g) else None
        return q, gripper

    def _reference(self):
        """The controller's newest reference ``(q, qd, qdd, stamp)`` if fresh, else None."""
        msg = self.commands.take()
        if msg is None:
            return None
        stamp = self._clock_time(msg.header.stamp)
        if self._ros_now() - stamp > self.get_parameter('reference_timeout').value:
            return None                      # no controller is publishing: start from the measurement
        try:
            q = reorder(msg.name, msg.position, self.names, 'joint_commands')
            qd = reorder(msg.name, msg.velocity, self.names, 'joint_commands') if len(msg.velocity) else 0 * q
            qdd = reorder(msg.name, msg.effort, self.names, 'joint_commands') if len(msg.effort) else 0 * q
        except (ValueError, IndexError):
            return None
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd)) and np.all(np.isfinite(qdd))):
            return None
        return q, qd, qdd, stamp

    def _publish_tool_path(self, q):
        """The tool poses of the plan (every other point) on ``planned_path``, for RViz or Foxglove."""
        arm_q = q[:, :self.arm.dof]
        tool = self.arm.fk(arm_q[::2] if len(arm_q) > 2 else arm_q)
        quats = Rotation.from_matrix(tool[:, :3, :3]).as_quat()
        self.pub_path.publish(self.codec.path(self.get_clock().now().nanoseconds, self.arm.base_frame,
                                              tool[:, :3, 3], quats))

    def _diagnose(self):
        """For /diagnostics: whether goals can be planned, and how many are in flight."""
        why = self._ready()
        flying = len(self.lifecycle.flights)
        if why is not None and 'not answered' not in why:
            return [('planner', Level.WARN, why, {'goals_in_flight': flying})]
        words = f'{flying} goal{"s" if flying != 1 else ""} in flight' if flying else 'ready, no goal in flight'
        return [('planner', Level.OK, f'{words}; method {self.planner.settings.method}, path_method '
                                      f'{self.planner.settings.path_method}', {'goals_in_flight': flying})]

    def close(self):
        self.states.destroy()
        self.commands.destroy()


def main(args=None):
    return run_node(PlannerNode, args, help=usage('picking-planner', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())


class CloudBuilder:
    """Builds each canopy cloud offered into the node's world on a thread of its own; a cloud that
    comes while one is built replaces the one waiting (only the newest is built)."""

    def __init__(self, node):
        self.node = node
        self._waiting, self._stop = None, False
        self._cv = threading.Condition()
        self._thread = threading.Thread(target=self._run, name='canopy', daemon=True)
        self._thread.start()

    def offer(self, msg):
        with self._cv:
            self._waiting = msg
            self._cv.notify()

    def stop(self):
        with self._cv:
            self._stop = True
            self._cv.notify()
        self._thread.join(2.0)

    def _run(self):
        logger, built = self.node.get_logger(), 0
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._stop or self._waiting is not None)
                if self._stop:
                    return
                msg, self._waiting = self._waiting, None
            try:
                points = cloud_points(msg, self.node.arm.base_frame)
                if len(points):
                    self.node.world.replace(canopy=points)
                else:
                    if self.node.world.canopy is not None:
                        logger.info('canopy cleared by an empty cloud on canopy_points')
                    self.node.world.clear_canopy()
                    built = 0
                    continue
            except ValueError as exc:
                logger.error(f'canopy_points refused, the old canopy kept: {exc}', throttle_duration_sec=5.0)
                continue
            built += 1
            if built == 1:
                logger.info(f'canopy from canopy_points: avoiding {self.node.world.words()}')
            self.node._world_changed.trigger()
