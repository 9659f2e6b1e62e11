"""``picking-planner``: the planner node, a ROS shell around the planning core and the goal flow.

Serves the actions ``move_to_pose``, ``follow_path`` and ``pick`` (picking_interfaces) and takes the
same goals on the topics ``goal_pose`` (PoseStamped), ``goal_path`` (PoseArray) and ``pick_target``
(PoseStamped), a tree's apples to harvest on ``harvest_targets`` (PoseArray), and a running pose or pick
goal's new target on ``retarget`` (PoseStamped). Every plan runs through the controller's
``follow_joint_trajectory`` action, stamped to take over where the controller's schedule reaches the
state it starts from (see picking_core.goals). Publishes each plan sent on ``planned_trajectory``, its
tool path on ``planned_path``, and every goal's transitions on ``planner_status`` (accepted, executing,
then succeeded, aborted, superseded, canceled or refused, with the reason).

The method is the ``method`` parameter (pose goals) or ``path_method`` (path goals), both settable at
run time; ``picking-goal --method`` sets them for one goal. Every parameter is validated when set.
"""

from __future__ import annotations

import threading

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from picking_common.params import declare, usage
from picking_common.run import run_node
from picking_common.scene_msgs import cloud_points, take_scene
from picking_common.status import Diagnostics, Level
from picking_common.tf import FrameError, FrameListener, stamp_seconds
from picking_common.topics import LATCHED, NEWEST
from picking_core.collision import Scene, World
from picking_core.fruit_map import MapSettings
from picking_core.goals.planning import GoalPlanner
from picking_core.goals.runner import GoalRunner
from picking_core.goals.start import Timing
from picking_core.kinematics import ArmModel
from picking_core.pick_cycle import PickSettings
from picking_core.planning import Planner, PlannerSettings
from picking_description import default_urdf, scene_path

from .inputs import GoalInputs
from .link import ControllerLink
from .parameters import COLLISION, PARAMS, PICK, SETTINGS
from .seen import SeenApples


class PlannerNode(Node):
    """ROS interface of the planner: its parameters, its world, and the goal flow's inputs and port."""

    def __init__(self, **kwargs):
        super().__init__('picking_planner', **kwargs)
        declare(self, PARAMS)
        value = self.get_parameter
        self.arm = ArmModel.from_urdf(value('urdf_path').value or default_urdf(), value('base_frame').value,
                                      value('tool_frame').value or None, value('joint_limits_path').value or None)
        missing = self.arm.missing_limits()
        if missing:
            raise ValueError(f'{missing}: give them in joint_limits_path (MoveIt\'s joint_limits.yaml)')
        # The compiled IK and forward kinematics load now (a fraction of a second from numba's cache), not on
        # the first goal.
        if not self.arm.load_ik() and self.arm.solver != 'numeric':
            self.get_logger().warning('the compiled IK did not load (is numba installed?): IK runs the vectorised '
                                      'closed form (the same solutions, slower)')
        self.names = list(self.arm.joint_names)
        self.planner = Planner(self.arm, self._settings({}))
        self.pick = PickSettings(**self._values(PICK, {})).validate(self.arm)
        p = {n: self.get_parameter(n).value for n in COLLISION}
        self.world = World(self.arm, self._scene_file(p['scene_file']), p['collision_clearance'],
                           p['avoid_collisions'])
        self._check_home(self.pick.home_positions)
        self.add_on_set_parameters_callback(self._on_parameters)
        # Goals, paths, clouds and scenes come in any frame /tf knows; the arm's base is this one there.
        self.base_tf = self.get_parameter('frame_prefix').value + self.arm.base_frame
        self.frames = FrameListener(self)
        self.link = ControllerLink(self)
        self.runner = GoalRunner(self.link, Timing(self.get_parameter('start_delay').value))
        self.runner.grasp_check = self.get_parameter('grasp_check').value
        self.link.runner = self.runner
        self.inputs = GoalInputs(self, self.runner, self.in_base)
        self.seen = SeenApples(self, self.runner, lambda header, timeout: self.in_base(header, 'detections', timeout),
                               MapSettings())
        self.seen.branches(self.world.scene.rods())
        self.create_timer(0.1, self._tick)
        # The world: a scene replaced whole by a latched MarkerArray, and the canopy by each cloud, built into its
        # octree on a thread of its own (a camera's clouds never wait for a plan, nor a plan for them).
        self.create_subscription(MarkerArray, 'scene', self._on_scene, LATCHED)
        self.create_subscription(PointCloud2, 'canopy_points', lambda msg: self._clouds.offer(msg), NEWEST)
        self._clouds = CloudBuilder(self)
        # A new canopy (built on its own thread) has the running plans checked again in the executor's.
        self._world_changed = self.create_guard_condition(self.runner.world_changed)
        self.diagnostics = Diagnostics(self, self.arm.name, self._diagnose)
        s = self.planner.settings
        self.get_logger().info(f'planning for {self.arm.name} ({self.arm.dof} joints, IK: {self.arm.solver}); method '
                               f'{s.method}, path_method {s.path_method}, speed_scale {s.speed_scale}; avoiding '
                               f'{self.world.words()}')

    def _tick(self):
        self.inputs.retarget_waiting()
        self.runner.tick()

    def _check_home(self, home):
        """A home (P0) in collision is refused (at start, or as a new parameter value), with what it touches."""
        home = np.asarray(home, float)
        contact = self.world.checker.first_contact(home[None]) if self.world.enabled else None
        if contact is not None:
            raise ValueError(f'home_positions {home.tolist()} put the arm in collision: {contact}')

    def goal_planner(self):
        """The goal planner of the moment (parameters may have changed the planner or the pick settings)."""
        return GoalPlanner(self.planner, self.pick, self.world)

    def in_base(self, header, what='goal', timeout=None):
        """The 4x4 transform from a message's frame to the arm's base (its stamp's, 0: the latest), waiting up to
        ``timeout`` s (None: ``transform_timeout``) for it; ValueError naming the frames and why when there is
        none."""
        frame = header.frame_id.lstrip('/')
        if frame in ('', self.arm.base_frame, self.base_tf):
            return np.eye(4)
        try:
            return self.frames.transform(self.base_tf, frame, stamp_seconds(header.stamp),
                                         self.get_parameter('transform_timeout').value if timeout is None else timeout)
        except FrameError as exc:
            raise ValueError(f'{what} in frame {frame!r}: {exc}') from None

    def _scene_file(self, path):
        scene = Scene.from_yaml(path or scene_path('workcell'))
        if scene.frame != self.arm.base_frame:
            raise ValueError(f'scene_file {path!r} is in frame {scene.frame!r}, not the arm\'s base frame '
                             f'{self.arm.base_frame!r} (a scene file is in the frame of the arm it is for)')
        return scene

    def _on_scene(self, msg):
        scene = take_scene(msg, lambda header: self.in_base(header, 'the scene marker'), self.get_logger())
        if scene is None:
            return
        self.world.replace(scene=scene)
        self.seen.branches(scene.rods())
        self.get_logger().info(f'scene replaced from the scene topic: avoiding {self.world.words()}')
        self.runner.world_changed()

    # -- parameters ------------------------------------------------------------------------------
    def _values(self, names, changes):
        values = {n: self.get_parameter(n).value for n in names}
        values.update({k: v for k, v in changes.items() if k in names})
        return values

    def _settings(self, changes):
        return PlannerSettings(**self._values(SETTINGS, changes)).validate()

    def _on_parameters(self, params):
        changes = {p.name: p.value for p in params}
        try:
            planner = Planner(self.arm, self._settings(changes)) if set(changes) & set(SETTINGS) else self.planner
            pick = PickSettings(**self._values(PICK, changes)).validate(self.arm) if set(changes) & set(PICK) \
                else self.pick
            scene = self._scene_file(changes['scene_file']) if 'scene_file' in changes else None
            if 'home_positions' in changes:
                self._check_home(pick.home_positions)
        except (ValueError, TypeError, OSError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.planner, self.pick = planner, pick
        self.world.replace(scene=scene, clearance=changes.get('collision_clearance'),
                           enabled=changes.get('avoid_collisions'))
        if 'start_delay' in changes:
            self.runner.timing.lead = float(changes['start_delay'])
        if 'grasp_check' in changes:
            self.runner.grasp_check = bool(changes['grasp_check'])
        return SetParametersResult(successful=True)

    def _diagnose(self):
        """For /diagnostics: whether goals can be planned, and how many are in flight."""
        why = self.runner.blocked()
        flying = len(self.runner.lifecycle.flights)
        if why is not None and 'not answered' not in why:
            return [('planner', Level.WARN, why, {'goals_in_flight': flying}), self.seen.diagnose()]
        words = f'{flying} goal{"s" if flying != 1 else ""} in flight' if flying else 'ready, no goal in flight'
        s = self.planner.settings
        return [('planner', Level.OK, f'{words}; method {s.method}, path_method {s.path_method}',
                 {'goals_in_flight': flying, **self.runner.retargets}), self.seen.diagnose()]

    def destroy_node(self):
        self._clouds.stop()
        return super().destroy_node()

    def close(self):
        self.link.close()
        self.frames.destroy()


class CloudBuilder:
    """Builds each canopy cloud offered into the node's world on a thread of its own; a cloud that comes while one
    is built replaces the one waiting (only the newest is built)."""

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

    def _next(self):
        with self._cv:
            self._cv.wait_for(lambda: self._stop or self._waiting is not None)
            msg, self._waiting = self._waiting, None
            return None if self._stop else msg

    def _run(self):
        logger, built = self.node.get_logger(), 0
        while (msg := self._next()) is not None:
            world = self.node.world
            try:
                points = cloud_points(msg, lambda header: self.node.in_base(header, 'canopy_points'))
            except ValueError as exc:
                logger.error(f'canopy_points refused, the old canopy kept: {exc}', throttle_duration_sec=5.0)
                continue
            if not len(points):
                if world.canopy is not None:
                    logger.info('canopy cleared by an empty cloud on canopy_points')
                world.clear_canopy()
                built = 0
                continue
            world.replace(canopy=points)
            built += 1
            if built == 1:
                logger.info(f'canopy from canopy_points: avoiding {world.words()}')
            self.node._world_changed.trigger()


def main(args=None):
    return run_node(PlannerNode, args, help=usage('picking-planner', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
