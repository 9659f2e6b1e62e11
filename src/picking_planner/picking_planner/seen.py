"""The apples the camera sees, for the planner: its detections (vision_msgs/Detection3DArray on ``detections``)
placed in the arm's base through /tf and fused by picking_core.fruit_map into confirmed targets; a
``harvest_seen`` message (std_msgs/Header, its stamp the goal's id) harvests those, grasped as a tree's
apples are (along +x), and the apples the camera shows while it runs join it; a swaying apple is aimed at its
sway when its turn comes (``GoalRunner.reaim``). Detections it cannot use are counted
with the reason on /diagnostics."""

from __future__ import annotations

from collections import Counter

from std_msgs.msg import Header

from picking_common.status import Level, stamp_key
from picking_common.topics import BURST
from picking_common.vision import read_detections
from picking_core.fruit_map import FruitMap
from picking_core.goals.lifecycle import Ending, Outcome
from picking_core.goals.requests import Goal, Kind, Target
from picking_core.harvest import SETTLED
from vision_msgs.msg import Detection3DArray

from .inputs import goal_id


class SeenApples:
    """``node``'s fruit map and its ``harvest_seen`` goals for ``runner``; ``in_base(header, timeout)`` places a
    frame in the arm's base (ValueError when it cannot)."""

    def __init__(self, node, runner, in_base, settings):
        self.node, self.runner, self.in_base = node, runner, in_base
        self.map = FruitMap(settings)
        self.refused = Counter()                 # detections left out before the map: the map counts its own
        node.create_subscription(Detection3DArray, 'detections', self._on_detections, 10)
        node.create_subscription(Header, 'harvest_seen', self._on_harvest, BURST)

    def branches(self, rods):
        """The scene's branches and wires, ``(ends (M, 2, 3), radii (M,))``: a detection inside one is refused."""
        self.map.branches = rods

    def _on_detections(self, msg):
        positions, covariances, diameters, scores, refused = read_detections(msg)
        for why in refused:
            self._refuse(why.split(': ', 1)[1])
        try:
            T = self.in_base(msg.header, 0.0)
        except ValueError as exc:
            self._refuse(f'a frame /tf does not place in the base ({msg.header.frame_id!r})', len(positions))
            self.node.get_logger().warning(f'detections ignored: {exc}', throttle_duration_sec=5.0)
            return
        R = T[:3, :3]
        placed = positions @ R.T + T[:3, 3]
        covariances = R @ covariances @ R.T
        # On the runner's clock (the ROS clock from its origin), as plans are timed: a swaying apple's fit predicts
        # where it will be when a plan closes the fingers.
        stamp = msg.header.stamp
        self.map.update(self.runner.port.seconds(stamp.sec * 1_000_000_000 + stamp.nanosec), placed, covariances,
                        diameters, scores)
        # The apples a pick passes slowly: those the map confirmed.
        self.node.world.replace(apples=[T[:3, 3] for T in self.map.grasp_poses()])
        self.runner.seen(placed, diameters, stamp_key(msg.header.stamp))
        self.runner.seen_more(self.map.grasp_poses(settled=SETTLED))
        self.runner.reaim(self.map.follow)

    def _refuse(self, why, n=1):
        self.refused[why] += n

    def _on_harvest(self, header):
        goal = Goal(Kind.HARVEST, goal_id(header), None, self.runner.port.wall(), stamp=stamp_key(header.stamp))
        # A sender that heard no answer yet sends the goal again: that is the harvest under way, not a new one of
        # the apples seen by then.
        if self.runner.resent(goal, header):
            return
        poses = self.map.grasp_poses()
        if not poses:
            self.runner.end(goal, Ending(Outcome.REFUSED, 'no apples seen: the fruit map has no confirmed apple (are '
                                                          'detections coming?)'))
            return
        follows = {i: self.map.follow(T[:3, 3]) for i, T in enumerate(poses)}
        goal.target = Target(Kind.HARVEST, tuple(poses), seen=True,
                             follows={i: f for i, f in follows.items() if f is not None})
        self.node.get_logger().info(f'harvest of the {len(poses)} apples seen (goal {goal.key})')
        self.runner.take(goal)

    def diagnose(self):
        """For /diagnostics: the map's tallies and why detections were refused."""
        counts = self.map.counts()
        refused = self.refused + self.map.refused        # before the map (the message, the frame) and in it
        words = (f"{counts['confirmed']} apples seen ({counts['tracks']} tracks) from {counts['detections']} "
                 f"detections in {counts['frames']} frames")
        if refused:
            words += '; refused: ' + ', '.join(f'{n} for {why}' for why, n in refused.most_common())
        return 'fruit map', Level.OK, words, {**counts, 'refused': sum(refused.values())}

