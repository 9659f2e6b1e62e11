"""``picking-harvester``: the coordinator of a platform of arms sharing one tree, a ROS shell around
:class:`~picking_core.coordination.PlatformRun`.

Takes a tree's apples on ``tree_targets`` (geometry_msgs/PoseArray in the ``platform`` frame), splits
them between the platform's arms (``picking_description/platforms/platform.yaml``: each arm's namespace, base pose and box),
and sends each arm's planner its share on ``<arm>/harvest_targets``, in the arm's base frame, at the time
the schedule keeps the arms apart with. Follows each arm on ``<arm>/planner_status``,
``<arm>/planned_trajectory`` (every released plan is checked against the other arms' released motion:
one that would come within the clearance stops its arm through ``<arm>/follow_joint_trajectory``'s
cancel service) and ``<arm>/joint_states`` (the closest approach measured). Reports on
``harvester_status`` (each round, each apple in a box, the decisions that kept the arms apart, the
final summary) and ``/diagnostics``. The arms' namespaces are relative: a platform runs side by side
with another under a namespace of its own. Everything goes over ROS topics and services, so each arm's
stack may run on a computer of its own (docs/deployment.md).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from action_msgs.srv import CancelGoal
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from picking_common.codec import Codec
from picking_common.joint_state import reorder, seconds
from picking_common.params import declare, usage
from picking_common.poses import msg_pose, pose_msg
from picking_common.run import run_node
from picking_common.status import Diagnostics, Level, stamp_key, status, status_values
from picking_common.tf import FrameError, FrameListener, stamp_seconds
from picking_common.topics import BURST, RELIABLE, LatestMessage
from picking_core.coordination import PlatformRun
from picking_core.kinematics import ArmModel
from picking_core.platform import SAMPLE, Coordinator, Platform, harvest_from_parameters
from picking_description import default_urdf, platform_path

from .parameters import HARVESTER as PARAMS
from .parameters import PARAMS as PLANNER_PARAMS

#: s a tree in another frame waits for its transform into the platform frame.
TRANSFORM_TIMEOUT = 0.5


class HarvesterNode(Node):
    """The coordinator's ROS interface; the behaviour is PlatformRun's."""

    def __init__(self, **kwargs):
        super().__init__('picking_harvester', **kwargs)
        values = declare(self, PARAMS)
        self.platform = Platform.from_yaml(values['platform_file'] or platform_path(),
                                           values['layout'] or None)
        # Each arm's planner as it plans by default (its parameters' defaults, the shipped ones), with its
        # own parameters of the platform file on top.
        arm = ArmModel.from_urdf(default_urdf())
        defaults = {p.name: p.default for p in PLANNER_PARAMS}
        self.coordinator = Coordinator.from_platform(self.platform,
                                                     lambda **own: harvest_from_parameters(arm, {**defaults, **own}),
                                                     clearance=values['clearance'],
                                                     slack=values['slack'], sample=SAMPLE)
        self.codec = Codec()
        self.frames = FrameListener(self)
        self.run, self.key = None, None
        self.pub_status = self.create_publisher(DiagnosticStatus, 'harvester_status', BURST)
        self.sub_tree = self.create_subscription(PoseArray, 'tree_targets', self._on_tree, BURST)
        self.arms = []
        for k, mount in enumerate(self.platform.arms):
            ns = mount.namespace
            arm = self.coordinator.harvests[k].arm
            self.arms.append(dict(
                ns=ns, names=arm.joint_names,
                targets=self.create_publisher(PoseArray, f'{ns}/harvest_targets', BURST),
                status=self.create_subscription(DiagnosticStatus, f'{ns}/planner_status',
                                                partial(self._on_arm_status, k), BURST),
                planned=self.create_subscription(JointTrajectory, f'{ns}/planned_trajectory',
                                                 partial(self._on_planned, k), RELIABLE, raw=True),
                # Taken in bulk by the one timer (a callback per message would cost more than the measuring).
                states=LatestMessage(self, JointState, f'{ns}/joint_states', reader=self.codec.state_reader(),
                                     depth=100),
                cancel=self.create_client(CancelGoal, f'{ns}/follow_joint_trajectory/_action/cancel_goal')))
        self.create_timer(0.1, self._every_tenth)
        self.diagnostics = Diagnostics(self, 'platform', self._diagnose)
        self.get_logger().info(f'coordinating {len(self.arms)} arms on one tree: '
                               + ', '.join(f'{m.namespace} at {np.round(m.base[:3, 3], 3).tolist()} m'
                                           for m in self.platform.arms))

    def _now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def _say(self, level, words, **values):
        self.pub_status.publish(status('picking_harvester', level, words, **values))
        if Level.of(level) == Level.OK:           # (rclpy wants one severity per call site)
            self.get_logger().info(words)
        else:
            self.get_logger().warning(words)

    # -- the tree ---------------------------------------------------------------------------------
    def _in_platform(self, header):
        """The transform of a tree's frame into the platform frame, through /tf; ValueError naming the frames."""
        frame = header.frame_id.lstrip('/')
        if frame in ('', self.platform.frame):
            return np.eye(4)
        try:
            return self.frames.transform(self.platform.frame, frame, stamp_seconds(header.stamp), TRANSFORM_TIMEOUT)
        except FrameError as exc:
            raise ValueError(f'the tree in frame {frame!r}: {exc}') from None

    def _on_tree(self, msg):
        key = stamp_key(msg.header.stamp)
        if self.run is not None and key == self.key:
            return                        # the same tree again (a sender that heard no answer yet)
        if self.run is not None and self.run.end is None:
            self._say(Level.WARN, f'tree {key} refused: a tree is being harvested (stop its arms first)', goal=key,
                      state='refused')
            return
        try:
            T = self._in_platform(msg.header)
            apples = [T @ msg_pose(p) for p in msg.poses]
            if not apples:
                raise ValueError('the tree has no apples (an empty PoseArray)')
        except ValueError as exc:
            self._say(Level.WARN, f'tree {key} refused: {exc}', goal=key, state='refused')
            return
        self.key = key
        self._say(Level.OK, f'tree {key} accepted: {len(apples)} apples for {len(self.arms)} arms; planning the '
                            'first round', goal=key, state='accepted', apples=len(apples))
        self.run = PlatformRun(self.coordinator, apples, self._now)
        self._every_tenth()

    # -- the arms ---------------------------------------------------------------------------------------
    def _every_tenth(self):
        run = self.run
        if run is None or run.end is not None and not run.events:
            return
        self._measure()
        for k, share in run.due():
            msg = PoseArray(poses=[pose_msg(T) for _, T in share])
            msg.header.frame_id = 'base_link'
            msg.header.stamp = self.get_clock().now().to_msg()
            run.sent(k, stamp_key(msg.header.stamp), [i for i, _ in share])
            self.arms[k]['targets'].publish(msg)
            self._say(Level.OK, f'{self.arms[k]["ns"]}: sent {len(share)} apples ({" ".join(str(i) for i, _ in share)})',
                      goal=self.key, state='executing', arm=self.arms[k]['ns'])
        self._report()

    def _report(self):
        run = self.run
        self._stop()
        for level, words in run.events:
            self._say(Level[level], words, goal=self.key, state='executing')
        run.events.clear()
        if run.end is not None and not getattr(run, 'reported', False):
            run.reported = True
            s = run.summary()
            state = 'aborted' if run.faulted() else 'succeeded'   # (stops and retries that still picked it all: reported)
            values = dict(goal=self.key, state=state, apples=s['apples'], picked=s['picked'],
                          harvest_time=s['harvest_time'], apples_per_hour=s['apples_per_hour'], rounds=s['rounds'],
                          closest_planned=s['closest_planned'], closest_measured=s['closest_measured'],
                          left=' '.join(str(i) for i in sorted(s['left'])))
            for ns, v in s['arms'].items():
                values[f'{ns}_picked'] = v['picked']
                values[f'{ns}_apples_per_hour'] = v['apples_per_hour']
            for i, reason in sorted(s['left'].items()):
                self._say(Level.WARN, f'apple {i} left on the tree: {reason}', goal=self.key, state='executing',
                          apple=i)
            self._say(Level.OK if state == 'succeeded' else Level.WARN, f'tree {state}: {run.words()}', **values)

    def _on_arm_status(self, k, msg):
        if self.run is None:
            return
        self.run.on_status(k, status_values(msg), msg.message)
        self._report()

    def _on_planned(self, k, raw):
        if self.run is None or self.run.arms[k].state != 'harvesting':
            return
        t = self.codec.read_trajectory(raw)
        q = reorder(t.joint_names, np.asarray(t.positions, float), self.arms[k]['names'], 'planned_trajectory')
        self.run.on_released(k, t.start, np.asarray(t.times, float), q)
        self._report()

    def _stop(self):
        """Stop the arms the run says must stop: cancel their controller's goals (the arm brakes to rest)."""
        for k, why in self.run.to_stop:
            self._say(Level.ERROR, f'{self.arms[k]["ns"]} stopped: {why}', goal=self.key, state='executing')
            self.arms[k]['cancel'].call_async(CancelGoal.Request())
        self.run.to_stop.clear()

    def _measure(self):
        """The joint states since the last tick, every arm's, compared at their stamps."""
        states = []
        for k, arm in enumerate(self.arms):
            for js in arm['states'].take_all():
                try:
                    q = reorder(js.name, js.position, arm['names'], 'joint_states')
                except ValueError:
                    continue
                states.append((seconds(js.header.stamp), k, q))
        for t, k, q in sorted(states, key=lambda s: s[0]):
            self.run.on_joint_state(k, q, t)

    def _diagnose(self):
        if self.run is None:
            return [('coordinator', Level.OK, f'{len(self.arms)} arms, no tree yet', {})]
        s = self.run.summary()
        state = 'done' if self.run.end is not None else 'harvesting'
        return [('coordinator', Level.OK, f'{state}: {s["picked"]} of {s["apples"]} apples picked',
                 {'picked': s['picked'], 'closest_measured': s['closest_measured']})]


def main(args=None):
    return run_node(HarvesterNode, args, help=usage('picking-harvester', __doc__, PARAMS))


if __name__ == '__main__':
    raise SystemExit(main())
