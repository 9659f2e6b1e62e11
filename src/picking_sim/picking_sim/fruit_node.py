"""The simulator's apples and camera on ROS: a thread of their own moves the apples along the published joint
states, captures the camera's frames on its clock and publishes each after its latency; what happens to an apple
goes out on ``fruit_events`` as it happens."""

from __future__ import annotations

import collections
import threading
import time
import traceback

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from picking_common.status import Level, status
from picking_common.topics import BURST, LATCHED
from picking_common.vision import cdr_agrees, detections_cdr, detections_msg
from picking_core.camera import CameraSettings, DepthCamera, look_at
from picking_core.fruit import Fate, Wind
from picking_core.kinematics.capsules import ArmCapsules

from .orchard import ArmSamples, Frames, fruit_world, tree_centres

#: Hz of fruit_truth.
TRUTH_RATE = 10.0
#: Hz the apples move at without a camera.
WORLD_RATE = 30.0
#: Events said at WARN (the rest at INFO).
BAD = ('missed grasp', 'knocked', 'knocked off', 'bruised', 'dropped', 'released on the tree')
COLOURS = {Fate.ON_TREE: (0.8, 0.1, 0.1), Fate.GRASPED: (1.0, 0.6, 0.0), Fate.HELD: (1.0, 0.6, 0.0),
           Fate.FALLING: (1.0, 1.0, 0.0), Fate.IN_BOX: (0.1, 0.8, 0.1), Fate.DROPPED: (0.4, 0.2, 0.1)}


class FruitSim:
    """The apples of ``node``'s tree and its camera (see the module)."""

    def __init__(self, node, world, scene, samples_of, camera, camera_frame, rate, latency):
        self.node, self.world, self.scene, self.samples_of = node, world, scene, samples_of
        self.camera, self.camera_frame = camera, camera_frame
        self.samples = collections.deque(maxlen=10_000)
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self._blockers = scene.rods()
        self.frames = Frames(rate if camera is not None else WORLD_RATE, latency, self.now())
        self.pub_events = node.create_publisher(DiagnosticStatus, 'fruit_events', BURST)
        self.pub_truth = node.create_publisher(MarkerArray, 'fruit_truth', 10)
        self.pub_detections = None
        if camera is not None:
            from tf2_msgs.msg import TFMessage

            from vision_msgs.msg import Detection3DArray

            from .state_publisher import transform_msg
            self.pub_detections = node.create_publisher(Detection3DArray, 'detections', 10)
            self._encode = detections_cdr if cdr_agrees() else detections_msg
            self.pub_static = node.create_publisher(TFMessage, '/tf_static', LATCHED)
            self.pub_static.publish(TFMessage(transforms=[transform_msg(node.base_tf, camera_frame, camera.mount,
                                                                        node.get_clock().now().to_msg())]))
        self._next_truth = 0.0
        self._truth_msg = None
        self._colours = {fate: ColorRGBA(r=r, g=g, b=b, a=1.0) for fate, (r, g, b) in COLOURS.items()}
        self._links = np.empty((0, 2, 3))         # the arm's capsules at the newest sample
        self.tree_scene = None                    # a tree's own scene (its branches), when it has one
        self.stop_fingers = None                  # called with the opening the fingers stop at (m; 0: none)
        self._finger_stop = 0.0

    @classmethod
    def from_parameters(cls, node, p, scene):
        """The node's apples and camera from its parameters, or None without a ``tree`` (ValueError: a bad tree
        or camera)."""
        # (An orchard's branches keep clear of the arm where it starts.)
        home = tuple(p['initial_positions'][:node.arm.dof])
        centres, tree_scene = tree_centres(p['tree'], node.arm, scene, home)
        if not p['tree'].strip():
            return None
        if tree_scene is not None:
            scene = tree_scene
        wind = Wind(p['wind.amplitude'], p['wind.frequency'], p['wind.direction'], p['wind.gust_rate'],
                    p['wind.gust_strength'], seed=p['wind.seed'])
        world = fruit_world(centres, scene, p['fruit_seed'], wind, t0=time.monotonic() + node._clock_offset)
        samples_of = ArmSamples(node.arm, ArmCapsules.from_arm(node.arm), list(node.names))
        camera = None
        if p['camera.enabled']:
            settings = CameraSettings(rate=p['camera.rate'], latency=p['camera.latency'], noise=p['camera.noise'],
                                      false_positives=p['camera.false_positives'], occlusion=p['camera.occlusion'],
                                      seed=p['camera.seed'])
            camera = DepthCamera(look_at(p['camera.position'], p['camera.look_at']), settings)
        sim = cls(node, world, scene, samples_of, camera, p['frame_prefix'] + p['camera.frame'],
                  p['camera.rate'], p['camera.latency'])
        sim.tree_scene = tree_scene
        node.get_logger().info(f'{len(world)} apples on the tree ({p["tree"]})' + (
            f'; a camera at {np.round(camera.origin, 3).tolist()} m reports them on detections at '
            f'{p["camera.rate"]:g} Hz, {p["camera.latency"] * 1e3:g} ms late' if camera is not None else ''))
        return sim

    def now(self):
        return time.monotonic() + self.node._clock_offset

    def start(self):
        self._thread = threading.Thread(target=self._run, name='fruit', daemon=True)
        self._thread.start()

    def stop(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def scene_changed(self, scene):
        with self.lock:
            self._blockers = scene.rods()

    # -- the thread --------------------------------------------------------------------------------------
    def _run(self):
        frames = self.frames
        while not self._stop.wait(max(0.0, frames.wake() - self.now())):
            try:
                self._turn(frames)
            except Exception:                 # a bug must be loud, and the arm's simulation goes on
                self.node.get_logger().error(f'the apples and camera failed:\n{traceback.format_exc()}',
                                             throttle_duration_sec=10.0)

    def _turn(self, frames):
        """What is due: the apples moved along the samples that came, a capture, frames to publish, the truth."""
        now = self.now()
        self._advance()
        if now >= frames.next_capture:
            missed = np.floor((now - frames.next_capture) / frames.period)
            frames.next_capture += frames.period * (missed + 1)
            if self.camera is not None:
                frames.hold(self.world.t, self._capture())
        for stamp, detections in frames.due(now):
            self.pub_detections.publish(self._encode(detections, self.camera_frame, int(round(stamp * 1e9))))
        if now >= self._next_truth:
            self._next_truth = now + 1.0 / TRUTH_RATE
            self.pub_truth.publish(self._truth())

    def _advance(self):
        taken = [self.samples.popleft() for _ in range(len(self.samples))]
        if not taken:
            return
        times, q = zip(*taken)
        tools, openings, links = self.samples_of(np.array(q))
        with self.lock:
            events = self.world.observe(np.array(times), tools, openings, links, self.samples_of.radii,
                                        self.samples_of.names)
            self._links = links[-1]
            stop = self.world.finger_stop()
        if stop != self._finger_stop and self.stop_fingers is not None:
            self._finger_stop = stop
            self.stop_fingers(stop)
        for e in events:
            self._say(e)

    def _capture(self):
        with self.lock:
            w = self.world
            present = (w.fate == Fate.ON_TREE) | (w.fate == Fate.GRASPED) | (w.fate == Fate.HELD) | \
                (w.fate == Fate.FALLING)
            ends, radii = self._blockers
            links = self._links
            blockers = np.concatenate([ends, links]) if len(links) else ends
            blocker_radii = np.concatenate([radii, self.samples_of.radii]) if len(links) else radii
            return w.t, self.camera.capture(w.p.copy(), w.radius, present, blockers, blocker_radii)

    def _say(self, e):
        text = e.words
        log = self.node.get_logger()
        bad = e.kind in BAD
        # (One call site per severity: rclpy ties a call site to one.)
        if bad:
            log.warning(text)
        else:
            log.info(text)
        x, y, z = (float(v) for v in e.where)
        offset = {} if e.offset is None else {'offset': f'{e.offset:.5f}'}
        self.pub_events.publish(status('picking_sim', Level.WARN if bad else Level.OK, text, apple=e.index,
                                       event=e.kind, t=f'{e.t:.3f}', x=x, y=y, z=z, **offset, **self.world.counts()))

    def _truth(self):
        """The apples as spheres coloured by fate: one message, its markers updated in place (building them anew
        at this rate would cost the thread more than moving the apples)."""
        out = self._truth_msg
        stamp = self.node.get_clock().now().to_msg()
        with self.lock:
            w = self.world
            if out is None:
                out = self._truth_msg = MarkerArray(markers=[self._marker(i, float(2 * w.radius[i]))
                                                             for i in range(len(w))])
            for i, m in enumerate(out.markers):
                m.header.stamp = stamp
                m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in w.p[i])
                fate = Fate(int(w.fate[i]))
                m.color, m.text = self._colours[fate], fate.words
        return out

    def _marker(self, i, diameter):
        m = Marker(ns='apples', id=i, type=Marker.SPHERE, action=Marker.ADD)
        m.header.frame_id = self.node.base_tf
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = diameter
        return m

    def diagnose(self):
        with self.lock:
            counts = self.world.counts()
        bad = counts['dropped'] or counts['bruised'] or counts['knocked'] or counts['missed_grasps']
        words = ', '.join(f'{v} {k.replace("_", " ")}' for k, v in counts.items() if v)
        return 'fruit', Level.WARN if bad else Level.OK, words or 'no apples', counts

