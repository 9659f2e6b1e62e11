"""The apple pick-and-place cycle of the paper's Table 1, as one plan (pure core).

P0 home -> P1 approach (pre-grasp pose, ``approach_distance`` back along the
tool's z axis; a joint-space LSPB move) -> P2 at the apple (a straight Cartesian
line) -> grasp (a dwell while the gripper closes) -> P3 lift and detach (a short
line up, or an arc that lifts and pulls back) -> P4 above the fruit box
(joint-space via-point LSPB through a lifted midpoint for the long transfer) -> P5 into the
box (a line down) -> release (a dwell while the gripper opens) -> back to P0
(via-point LSPB up through P4).

With ``blend`` the arm passes P1, P3 and P4 at speed instead of stopping there, and
``blend_radius`` (at the apple) and ``box_blend_radius`` (over the box) round those
corners (see :class:`PickSettings`).

The gripper is a joint of the plan (``gripper_joint``, the finger opening in m),
so grasp and release reach every subscriber of ``joint_states`` with their times.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from . import approaches, around, geometry, trajectory
from .kinematics import Unreachable
from .planning import JOINT_METHODS, Plan
from .planning.remembered import Remembered

#: The shipped arm's home, rad: P0 of the pick cycle (tool level, facing the tree), where the simulator
#: starts; and its gripper's opening when open, m.
HOME_POSITIONS = (0.0, 0.2, 1.6, 0.0, -0.23, 0.0)
GRIPPER_OPEN = 0.09
#: The gripper's joint in the pick cycle's plans (its finger opening, m).
GRIPPER_JOINT = 'gripper_joint'


def gripper_column(arm):
    """The name of a plan's finger-opening column: the arm's gripper joint, else :data:`GRIPPER_JOINT`."""
    return arm.gripper_joint or GRIPPER_JOINT
LIFT_METHODS = ('line', 'arc', 'back')
#: With ``blend``: the speeds tried where a joint move meets a line, as fractions of the line's fastest.
BLEND_SPEEDS = (0.0, 0.3, 0.6, 0.9)
TRANSFER_METHODS = ('via_lspb', 'quintic_via', 'optimal')
#: s before the straight approach the tool begins to take on the apple's motion (gently: a line to the apple is
#: timed to the joints' limits, and has no room for more).
RIDE_RAMP = 0.5
#: Shares of the apple's motion a ride tries to take on, the largest first: a ride that would break a joint limit
#: with all of it (a re-aim starting close to the straight approach squeezes the ramp) takes on what the limits allow.
RIDE_SHARES = (1.0, 0.75, 0.5, 0.25)
#: Fraction of the planner's speed the moves of a pick that rides its apple (:meth:`PickCycle.plan` ``rides``)
#: are planned at, the approach, the line to the apple and the lift: room in the joints' limits for its motion.
RIDE_SPEED = 0.85
#: s: the arm dwells at least this long at the drop point, whatever ``release_lead`` takes of the release.
MIN_DWELL = 0.02
RIDDEN = ('P1 approach', 'P2 to the apple', 'P3 lift and detach')


@dataclass(frozen=True)
class PickSettings:
    """The cycle's geometry and timing (config/pick_cycle.yaml). SI units, radians.

    Attributes
    ----------
    home_positions : list of float
        P0, rad (one per arm joint).
    approach_distance : float
        P1 lies this far back from the apple along the tool's z axis, m.
    lift_height : float
        P3 lies this far above the apple (``back``: this far back from it), m.
    lift_method : str
        ``line`` (straight up), ``arc`` (up and back along a quarter-arc: twists the
        stem less) or ``back`` (straight back out along the approach: the way out
        from under a twig above the apple).
    approach_method : str
        Joint-space profile of the moves to P0 and P1: ``lspb`` (the paper's linear
        segments with parabolic blends, the fastest of the paper's profiles),
        ``quintic``, ``cubic`` or ``optimal`` (jerk-limited and time-optimal, Ruckig).
    grasp_time, release_time : float
        Dwells while the gripper closes and opens, s.
    box_position : list of float
        P5, the drop point in the box, m (base frame).
    box_drop_height : float
        P4 lies this far above P5, m.
    place_orientation_rpy : list of float
        Tool orientation over the box, roll-pitch-yaw in rad (default: pointing down).
    place_yaw_free : bool
        An apple drops the same whatever the gripper's turn about the vertical: let
        the planner choose that turn (in 30 degree steps) for the quickest transfer
        and return.
    transfer_method : str
        ``via_lspb``, ``quintic_via`` or ``optimal`` for the transfer and the return.
    transfer_lift : float
        The transfer's via point is the joint-space midpoint with the shoulder lifted
        back by this much, rad (clearance over the canopy and the box rim).
    gripper_open, gripper_closed : float
        Finger opening, m.
    blend : bool
        Pass P1, P3 and P4 at speed instead of stopping there: the approach flows into
        the line to the apple, the lift into the transfer, the transfer into the line
        into the box, and the way back rises straight out of the box (a line to P4) into
        the move home (each junction at the quickest of BLEND_SPEEDS, the lines straight).
        Needs the ``optimal`` approach and transfer methods and the planner's
        ``cartesian_profile: optimal`` (jerk-limited: the joints' velocity and
        acceleration stay continuous through the blends).
    blend_radius : float
        With ``blend``: the joint moves meet the lines this far from P1 and P3, m (0: at
        those points). The lines to the apple and up from it are that much shorter, and
        each joint move rounds its corner: the approach flows into the line to the apple,
        and the transfer rises the rest of the way to P3 while the waist starts its turn.
        Less than half of ``approach_distance`` and ``lift_height``, so that most of every
        line at the apple stays straight (the apple is pulled straight off for at least
        half the lift). How close the tool passes each corner and what the cycle gains are
        in ``docs/benchmarks.md`` (row 7).
    box_blend_radius : float
        With ``blend``: the transfer meets the line into the box, and the rise out of the box
        meets the next move, this far below P4, m (0: at P4). The line into the box is the
        slow part of the place and the waist swings its limit all through the transfer: a
        large radius (most of ``box_drop_height``) lowers the apple during the swing and
        leaves the last centimetres above the drop point straight down. Less than
        ``box_drop_height``; the rounded path is checked against the box like every other.
    approach_cone : float
        When the requested approach is blocked or out of reach, other grasp axes are tried
        this far from it, rad (0: only the requested one; see :mod:`picking_core.approaches`).
    apple_region : float
        Radius around the apple's centre where touching is allowed (the apple and its stem), m.
    apple_pass_speed : float
        In a harvest or a pick (with a collision checker), the fastest a link may pass an apple still
        on the tree (a harvest's others, the apples the planner's world knows), m/s: a joint move
        passing one faster, or pressing one off its stem, goes around those apples where a way is
        found, else is slowed past them (:mod:`picking_core.collision.fruit`); 0: the other apples
        are not looked at.
    hold_time : float
        A pick of a moving apple whose closing is not sure waits at the stand-off (P1) for a
        calmer moment at most this long from its first hold, s; then it backs off home and
        ends without closing (:mod:`picking_core.moving_pick`).
    release_lead : float
        The fingers begin to open this long before the tool reaches P5, on the line into the box,
        s (at most that line's duration): the arm dwells at P5 only for the rest of the release
        (at least ``MIN_DWELL``). The apple drops from at most the line's last centimetres; 0: the
        whole release is a dwell at P5, as in the paper.
    """

    home_positions: tuple = HOME_POSITIONS
    approach_distance: float = 0.10
    lift_height: float = 0.06
    lift_method: str = 'line'
    approach_method: str = 'lspb'
    grasp_time: float = 0.25
    release_time: float = 0.25
    box_position: tuple = (0.05, -0.55, 0.30)
    box_drop_height: float = 0.12
    place_orientation_rpy: tuple = (np.pi, 0.0, 0.0)
    place_yaw_free: bool = True
    transfer_method: str = 'via_lspb'
    transfer_lift: float = 0.15
    gripper_open: float = GRIPPER_OPEN
    gripper_closed: float = 0.055
    blend: bool = False
    blend_radius: float = 0.0
    box_blend_radius: float = 0.0
    approach_cone: float = float(np.radians(45.0))
    apple_region: float = 0.06
    apple_pass_speed: float = 0.9
    hold_time: float = 3.0
    release_lead: float = 0.0

    def validate(self, arm):
        """Check every value against the arm; returns self."""
        if len(self.home_positions) != arm.dof or not np.all(np.isfinite(self.home_positions)):
            raise ValueError(f'home_positions must be {arm.dof} finite joint values (rad)')
        if not arm.within_limits(np.asarray(self.home_positions, float)):
            raise ValueError(f'home_positions {list(self.home_positions)} are outside the joint limits')
        tool = arm.fk(np.asarray(self.home_positions, float))[:3, 3]
        if tool[2] < 0.0:
            raise ValueError(f'home_positions {list(self.home_positions)} put the tool {-tool[2]:.3f} m below the '
                             f"arm's base ({arm.tool_frame} at z = {tool[2]:.3f} m in {arm.base_frame})")
        if not (np.isfinite(self.transfer_lift) and 0.0 <= self.transfer_lift < 1.0):
            raise ValueError(f'transfer_lift must be in [0, 1) rad, got {self.transfer_lift}')
        for name in ('approach_distance', 'lift_height', 'grasp_time', 'release_time', 'box_drop_height',
                     'hold_time'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a finite number > 0, got {value}')
        # (A line is screened point by point along its length: one longer than the arm reaches across is refused
        # here, not after screening it.)
        across = 2.0 * float(arm.reach[1]) + 1.0
        for name in ('approach_distance', 'lift_height', 'box_drop_height'):
            if getattr(self, name) > across:
                raise ValueError(f'{name} {getattr(self, name)} m is longer than the arm reaches across ({across:.2f} m)')
        for name, n in (('box_position', 3), ('place_orientation_rpy', 3)):
            value = np.asarray(getattr(self, name), float)
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ValueError(f'{name} must be {n} finite numbers')
        if self.approach_method not in JOINT_METHODS:
            raise ValueError(f'approach_method must be one of {JOINT_METHODS}, got {self.approach_method!r}')
        if self.lift_method not in LIFT_METHODS:
            raise ValueError(f'lift_method must be one of {LIFT_METHODS}, got {self.lift_method!r}')
        if self.transfer_method not in TRANSFER_METHODS:
            raise ValueError(f'transfer_method must be one of {TRANSFER_METHODS}, got {self.transfer_method!r}')
        if not 0.0 <= self.gripper_closed < self.gripper_open:
            raise ValueError('need 0 <= gripper_closed < gripper_open')
        if not (np.isfinite(self.blend_radius) and self.blend_radius >= 0.0):
            raise ValueError(f'blend_radius must be a finite number >= 0 m, got {self.blend_radius}')
        if self.blend_radius > 0.0:
            if not self.blend:
                raise ValueError('blend_radius needs blend: true (the joint moves meet the shortened lines at speed)')
            shortest = min(('approach_distance', self.approach_distance), ('lift_height', self.lift_height),
                           key=lambda x: x[1])
            if self.blend_radius >= 0.5 * shortest[1]:
                raise ValueError(f'blend_radius {self.blend_radius} m must be less than half of every line: '
                                 f'{shortest[0]} is {shortest[1]} m')
        if not (np.isfinite(self.box_blend_radius) and 0.0 <= self.box_blend_radius < self.box_drop_height):
            raise ValueError(f'box_blend_radius must be >= 0 m and less than box_drop_height '
                             f'({self.box_drop_height} m), got {self.box_blend_radius}')
        if self.box_blend_radius > 0.0 and not self.blend:
            raise ValueError('box_blend_radius needs blend: true (the joint moves meet the shortened lines at speed)')
        if not (np.isfinite(self.approach_cone) and 0.0 <= self.approach_cone <= np.pi / 2):
            raise ValueError(f'approach_cone must be in [0, pi/2] rad, got {self.approach_cone}')
        if not (np.isfinite(self.apple_region) and self.apple_region >= 0.0):
            raise ValueError(f'apple_region must be a finite number >= 0 m, got {self.apple_region}')
        if not (np.isfinite(self.release_lead) and self.release_lead >= 0.0):
            raise ValueError(f'release_lead must be a finite number >= 0 s, got {self.release_lead}')
        if not (np.isfinite(self.apple_pass_speed) and self.apple_pass_speed >= 0.0):
            raise ValueError(f'apple_pass_speed must be a finite number >= 0 m/s, got {self.apple_pass_speed}')
        if self.blend and not (self.approach_method == self.transfer_method == 'optimal'):
            raise ValueError('blend needs approach_method and transfer_method optimal (jerk-limited moves to '
                             'and from moving states)')
        return self


def _smoothstep(x):
    """0 to 1 as ``x`` goes 0 to 1, its first two derivatives 0 at both ends (the quintic)."""
    return x ** 3 * (10.0 - 15.0 * x + 6.0 * x ** 2)


def _toward(T_from, T_to, distance):
    """The pose ``distance`` m from ``T_from`` on the straight line to ``T_to``, its orientation
    turned in proportion (as a line's slerp)."""
    delta = T_to[:3, 3] - T_from[:3, 3]
    frac = distance / np.linalg.norm(delta)
    out = T_from.copy()
    out[:3, 3] += frac * delta
    turn = Rotation.from_matrix(T_from[:3, :3].T @ T_to[:3, :3]).as_rotvec()
    out[:3, :3] = T_from[:3, :3] @ Rotation.from_rotvec(frac * turn).as_matrix()
    return out


@functools.lru_cache(maxsize=16)
def _rpy_matrix(rpy):
    """The rotation matrix of roll, pitch, yaw ``rpy`` (a tuple, rad; fixed axes x, y, z), read-only:
    the place orientation is a setting, the same for every cycle (scipy takes tens of µs)."""
    out = Rotation.from_euler('xyz', rpy).as_matrix()
    out.flags.writeable = False
    return out


#: The gripper's turns about the vertical that the quickest place chooses from: 30 degree steps.
_PLACE_TURNS = Rotation.from_euler('z', np.radians(np.arange(-180, 180, 30))[:, None]).as_matrix()
_PLACE_TURNS.flags.writeable = False


def _level_back(T):
    """The level unit vector back along pose ``T``'s z (zero for a vertical z)."""
    back = -T[:3, 2] * np.array([1.0, 1.0, 0.0])
    return back / max(np.linalg.norm(back), 1e-9)


def _lift_end(T, lift, height):
    """Where ``lift`` from the grasp pose ``T`` ends, ``height`` m up (``line``), back along the grasp axis
    (``back``), or both, back level (``arc``)."""
    if lift == 'back':
        return _offset(T, [0.0, 0.0, -height])
    end = T.copy()
    end[:3, 3] += height * ((_level_back(T) if lift == 'arc' else 0.0) + np.array([0.0, 0.0, 1.0]))
    return end


def _offset(T, local):
    """Pose ``T`` moved by ``local`` in its own frame."""
    out = T.copy()
    out[:3, 3] = T[:3, :3] @ np.asarray(local, float) + T[:3, 3]
    return out



@dataclass
class _Draft:
    """A cycle being planned: its knot poses and joints (P1 and P4 where the blends meet the lines), the
    detours and slowed joint moves asked for, and the parts planned so far with their Cartesian paths."""

    poses: dict
    q: dict
    home: np.ndarray
    detours: dict
    q1: np.ndarray
    q4: np.ndarray
    lift: str = 'line'
    slow: dict = field(default_factory=dict)
    q_apple: np.ndarray = None
    q_top: np.ndarray = None
    q_box: np.ndarray = None
    flying: tuple = None
    approach_time: float = None
    parts: list = field(default_factory=list)
    cart: list = field(default_factory=list)

    def add(self, label, method, traj, path=None):
        self.parts.append((label, method, traj))
        if path is not None:
            self.cart.append((len(self.parts) - 1, path))

class PickCycle:
    """Plans Table 1 for one apple with a :class:`~picking_core.planning.Planner`; with a
    :class:`~picking_core.collision.CollisionChecker`, only cycles clear of its obstacles."""

    def __init__(self, planner, settings=PickSettings(), checker=None):
        # Remembered: a cycle planned again (a detour, another approach, the next apple) reuses its moves.
        self.planner = planner if isinstance(planner, Remembered) else Remembered(planner)
        self.arm = planner.arm
        self.s = settings
        self.checker = checker
        self._slowed = {}

    def key_poses(self, T_apple, lift=None):
        """P1..P5 as 4x4 poses (P0 is a joint configuration); P3 where ``lift`` (one of :data:`LIFT_METHODS`;
        None: the settings') ends."""
        s = self.s
        P2 = np.asarray(T_apple, float)
        P1 = _offset(P2, [0.0, 0.0, -s.approach_distance])
        P3 = _lift_end(P2, lift or s.lift_method, s.lift_height)
        P5 = np.eye(4)
        P5[:3, :3] = _rpy_matrix(tuple(s.place_orientation_rpy))
        P5[:3, 3] = s.box_position
        P4 = P5.copy()
        P4[2, 3] += s.box_drop_height
        return {'P1': P1, 'P2': P2, 'P3': P3, 'P4': P4, 'P5': P5}

    def plan(self, start, T_apple, gripper_start=None, from_box=False, home_after=True, neighbours=None,
             approach_time=None, from_here=False, rides=False):
        """The whole cycle from ``start = (q, qd, qdd)``; a Plan with the gripper as last joint.

        A harvest chains cycles (:mod:`picking_core.harvest`): ``from_box`` starts at rest in the
        box, where the cycle before ended, and rises straight out of it into the approach instead
        of going home first; ``home_after=False`` ends at rest in the box after the release.

        When the requested approach is out of reach or (with a checker) touches an obstacle, other
        approaches within ``approach_cone`` are tried (:func:`~picking_core.approaches.clear_cycle`;
        the plan's ``extra`` says which was taken: ``approach`` in words, ``approach_tilt`` and
        ``approach_roll`` in rad). Raises Unreachable naming the knot
        point that cannot be reached, or :class:`~picking_core.approaches.Blocked` naming the
        obstacle. With a checker, ``neighbours`` (:class:`~picking_core.collision.fruit.Neighbours`: the
        other apples on the tree) are passed slowly: a joint move that would pass one fast goes around them.
        ``approach_time`` s: the least the move to P1 may last (a pick timed to close on a moving apple when it
        gets there, :mod:`picking_core.moving_pick`; a detour is not stretched). ``from_here``: the approach
        leaves ``start`` even at rest, not by way of home (a pick that waited at its stand-off). ``rides``: the
        approach and its line are planned at :data:`RIDE_SPEED`, room for :meth:`ride` on a moving apple.
        """
        return approaches.clear_cycle(
            self, lambda T, detours=None, branch=None, slow=None, lift=None: self._plan(
                start, T, gripper_start, from_box, home_after, detours, branch, slow, approach_time, from_here,
                rides, lift),
            T_apple, neighbours)

    def _plan(self, start, T_apple, gripper_start, from_box, home_after, detours=None, branch=None, slow=None,
              approach_time=None, from_here=False, rides=False, lift=None):
        """The cycle for the grasp pose ``T_apple`` as requested (:meth:`plan`); ``detours`` maps the
        label of a joint move (:data:`~picking_core.approaches.DETOURS`) to joint waypoints it passes through on its way
        (a collision-free path around an obstacle); ``branch``: the joints at P1 (another IK solution
        than the one nearest home); ``slow`` maps the label of a joint move to the fraction of the planner's
        speed it runs at (past apples it would bruise); ``lift``: the way out with the apple (one of
        :data:`LIFT_METHODS`; None: the settings'). The steps of Table 1 in order."""
        start = self.planner.check_start(start)
        if self.s.blend and (self.planner.settings.cartesian_profile != 'optimal' or self.planner.settings.duration):
            raise ValueError('blend needs the planner\'s cartesian_profile optimal and no fixed duration (lines '
                             'entered and left at speed)')
        if rides:
            # (Timed to the limits, the approach and its line would leave no room for the apple's motion on top.)
            slow = {**{label: approaches.Slowed(RIDE_SPEED) for label in RIDDEN}, **(slow or {})}
        d = self._knots(T_apple, branch, detours or {}, lift)
        d.slow = dict(slow or {})
        d.approach_time = approach_time
        rise_line = None
        if not from_box and self._flies_on(start, from_here):
            d.flying = start
            try:
                self._reach_apple(d, None)
            except Unreachable:
                # (The move from the moving arm would cross a limit: it brakes and goes home first, as before.)
                d = self._knots(T_apple, branch, detours or {}, lift)
                d.slow, d.approach_time = dict(slow or {}), approach_time
        if d.flying is None:
            rise_line = self._leave_start(d, start, from_box)
            self._reach_apple(d, rise_line)
        d.add('grasp', 'dwell', trajectory.hold(d.q_apple, self._gripper_time(self.s.grasp_time)))
        self._carry_to_box(d)
        # The fingers begin to open on the last of the line into the box: the arm dwells for the rest.
        into_box = d.parts[-1][2].duration
        lead = min(self.s.release_lead, into_box, self._gripper_time(self.s.release_time) - MIN_DWELL)
        d.add('release', 'dwell', trajectory.hold(d.q_box, self._gripper_time(self.s.release_time) - max(lead, 0.0)))
        if home_after:                        # (else at rest in the box: the next apple's cycle rises out of it)
            for part in self._home_from_box((d.q_box, 0.0 * d.q_box, 0.0 * d.q_box), d.detours.get('P0 back home'),
                                            self._mover(d, 'P0 back home')):
                d.add(*part)
        return self._with_gripper(d.parts, d.cart, gripper_start)

    def _knots(self, T_apple, branch, detours, lift=None):
        """Step C first: the knot poses P1-P5 and their joints, every one reachable before anything moves (P4
        and P5 may turn about the vertical with ``place_yaw_free``); the blend points near P1 and P4."""
        s, arm = self.s, self.arm
        poses = self.key_poses(T_apple, lift)
        home = np.asarray(s.home_positions, float)
        q, seed = {}, home
        for name in ('P1', 'P2', 'P3', 'P4', 'P5'):
            try:
                q[name] = arm.check_reachable(poses[name], seed=seed)
            except Unreachable as exc:
                if not (s.place_yaw_free and name in ('P4', 'P5')):
                    raise Unreachable(f'{name} ({_LABELS[name]}): {exc}') from None
                q[name] = None
            seed = q[name] if q[name] is not None else seed
        if branch is not None:
            q['P1'] = arm.check_joints(branch, 'branch')
        if s.place_yaw_free:
            poses, q['P4'], q['P5'] = self.quickest_place(poses, q['P3'], home)
        # With blend radii the joint moves meet the lines that far from P1, P3 and P4: the
        # lines are that much shorter, and the corners are rounded by the joint moves.
        r, r_box = s.blend_radius, s.box_blend_radius
        q1 = q['P1'] if r == 0.0 else self._ik_toward('P1', poses['P1'], poses['P2'], r, q['P1'])
        q4 = q['P4'] if r_box == 0.0 else self._ik_toward('P4', poses['P4'], poses['P5'], r_box, q['P4'],
                                                          'box_blend_radius')
        return _Draft(poses, q, home, detours, q1, q4, lift or s.lift_method)

    @property
    def _speeds(self):
        """The speeds tried where a joint move meets a line (at rest only, without blends)."""
        return BLEND_SPEEDS if self.s.blend else (0.0,)

    def _blend_state(self, traj, at_end):
        """``(velocity, acceleration)`` where a blend meets ``traj`` (its end or start); None without."""
        if not self.s.blend:
            return None
        return (traj.end_state() if at_end else traj.start_state())[1:]

    def _flies_on(self, start, from_here=False):
        """Whether the approach leaves ``start`` as it moves (a jerk-limited move from any state), not after a brake
        to rest and the way home: a pick whose target moved while the arm approached it carries on towards it;
        ``from_here`` at rest too (any method)."""
        _, qd, qdd = self.planner.check_start(start)
        moving = bool(np.abs(qd).max() >= 1e-4 or np.abs(qdd).max() >= 1e-3)
        return (from_here and not moving) or (moving and self.s.approach_method == 'optimal')

    def _leave_start(self, d, start, from_box):
        """From the start: brake to rest and go home (P0), or, from the box, the line out of it (returned as a
        function of its speed at the top, planned with the approach that follows it)."""
        pl, s = self.planner, self.s
        if from_box:
            return self._out_of_the_box(start)[2]
        stop, q_rest = pl.come_to_rest(start)
        if stop is not None:
            d.add('brake', 'quintic', stop)
        mover = self._mover(d, 'P0 home')
        if 'P0 home' in d.detours:
            d.add('P0 home', s.transfer_method, self._detour([q_rest, *d.detours['P0 home'], d.home], None, None, mover))
        elif np.abs(q_rest - d.home).max() > 1e-4:
            d.add('P0 home', s.approach_method, mover.joint_move(q_rest, d.home, s.approach_method))
        return None

    def _approach(self, d, line, rise=None):
        """Home (or the end of the ``rise`` out of the box) -> the start of the line to the apple (P1), arriving
        as fast as the line starts."""
        vf, af = self._blend_state(line, False) or (None, None)
        if rise is None and d.flying is not None:
            q0, v0, a0 = d.flying
        else:
            q0 = d.home if rise is None else rise.end_state()[0]
            v0, a0 = (None, None) if rise is None else (self._blend_state(rise, True) or (None, None))
        mover = self._mover(d, 'P1 approach')
        if 'P1 approach' in d.detours:
            return self._detour([q0, *d.detours['P1 approach'], line.start_state()[0]],
                                None if v0 is None else (v0, a0), None if vf is None else (vf, af), mover)
        least = d.approach_time if self.s.approach_method == 'optimal' else None
        return mover.joint_move(q0, line.start_state()[0], self.s.approach_method, duration=least, v0=v0, a0=a0,
                                vf=vf, af=af)

    def _reach_apple(self, d, rise_line):
        """P1 approach and P2, the straight line to the apple (after the line out of the box, from the box)."""
        pl, arm = self._mover(d, 'P2 to the apple'), self.arm

        def to_apple(speed, rest):
            return pl.line(d.q1, arm.fk(d.q1), d.poses['P2'], (speed, 0.0), rest)
        if rise_line is not None:
            # The line to the apple as for an approach from the top of the box at rest; then the
            # speed out of the box for that line.
            at_rest = rise_line(0.0, None)[0]
            _, (line, path) = self._quickest(self._speeds, to_apple, lambda ln: self._approach(d, ln, at_rest))
            moved, (rise, rise_path) = self._quickest(self._speeds, rise_line, lambda r: self._approach(d, line, r))
            d.add('P4 out of the box', 'line', rise, rise_path)
        else:
            moved, (line, path) = self._quickest(self._speeds, to_apple, lambda ln: self._approach(d, ln))
        d.add('P1 approach', self.s.approach_method, moved)
        d.add('P2 to the apple', 'line', line, path)
        d.q_apple = line.end_state()[0]

    def _transfer(self, d, lift, into_box=None):
        """The end of the lift -> clearance -> P4 (the start of the line into the box, once planned)."""
        q_lift = lift.end_state()[0]
        q_box = d.q4 if into_box is None else into_box.start_state()[0]
        # The via point lies between the corners P3 and P4, where the transfer would turn without blends.
        corner = q_lift if d.q_top is None else d.q_top
        through = d.detours.get('P4 above the box', [self._clearance(corner, d.q['P4'])])
        return self._mover(d, 'P4 above the box').via(
            np.array([q_lift, *through, q_box]), self.s.transfer_method, self._blend_state(lift, True),
            None if into_box is None else self._blend_state(into_box, False))

    def _carry_to_box(self, d):
        """P3, the lift that detaches the apple, flowing into the transfer to P4, and P5, the line into the box."""
        s, pl, arm = self.s, self.planner, self.arm
        d.q_top = None if s.blend_radius == 0.0 else self._top(d.q_apple, d.poses, d.lift)  # the corner at P3
        lifter = self._mover(d, 'P3 lift and detach')

        def lifted(f, rest=None):
            return self._lift(d.q_apple, d.poses, f, rest, lifter, d.lift)
        # The lift flows into the transfer (stopping at P4 for this choice; without blends there is no
        # choice to make, and the transfer is planned once, below) ...
        if s.blend:
            _, (lift, path) = self._quickest(self._speeds, lifted, lambda ln: self._transfer(d, ln))
        else:
            lift, path = lifted(0.0)
        d.add('P3 lift and detach', d.lift, lift, path)
        # ... and the transfer into the line into the box.
        moved, (line, path) = self._quickest(
            self._speeds, lambda f, rest: pl.line(d.q4, arm.fk(d.q4), d.poses['P5'], (f, 0.0), rest),
            lambda ln: self._transfer(d, lift, ln))
        d.add('P4 above the box', s.transfer_method, moved)
        d.add('P5 into the box', 'line', line, path)
        d.q_box = line.end_state()[0]

    def _detour(self, qs, start, end, mover=None):
        """A joint move through the waypoints ``qs``, timed with the transfer's via-point method (from
        and to rest unless that method is ``optimal``, which also starts and ends moving) by ``mover`` (a
        planner; default the cycle's)."""
        method = self.s.transfer_method
        if method != 'optimal':
            start = end = None
        return (mover or self.planner).via(np.array(qs), method, start, end)

    def _mover(self, d, label):
        """The planner of joint move ``label``: the cycle's, or one slowed as ``d.slow`` says (an
        :class:`~picking_core.approaches.Slowed`: the whole move, or only its stretch past the apples)."""
        slowed = d.slow.get(label)
        if slowed is None:
            return self.planner
        fraction = slowed.fraction
        if fraction not in self._slowed:
            self._slowed[fraction] = Remembered(self.planner.with_settings(
                speed_scale=self.planner.settings.speed_scale * fraction))
        if slowed.window is None:
            return self._slowed[fraction]
        return _SlowPast(self.planner, self._slowed[fraction], slowed)

    def back_home(self, start, gripper_start=None):
        """From rest in the box (where a harvest's last cycle ended) back home: a Plan with the gripper;
        with a checker, clear of its obstacles (around them if need be), else Blocked naming the contact."""
        def plan(detours=None):
            parts = self._home_from_box(start, (detours or {}).get('P0 back home'))
            cart = [(k, part[3]) for k, part in enumerate(parts) if part[3] is not None]
            return self._with_gripper([part[:3] for part in parts], cart, gripper_start)
        done, contact = approaches.clear_plan(self, plan, None)
        if contact is not None:
            raise approaches.Blocked(f'the way home from the box hits {contact}')
        return done

    def stand_off(self, start, T_apple):
        """From ``start`` (q, qd, qdd) to rest at P1 of a pick of ``T_apple``: where a pick of a moving apple waits
        for a closing it is sure of. The plan has no gripper column (the fingers keep their opening); around what
        the checker sees, else Blocked naming the contact."""
        return around.plan_pose(self.planner, self.checker, start, self.key_poses(T_apple)['P1'])

    def ride(self, plan, motion, closes, shares=RIDE_SHARES):
        """``plan`` (a pick cycle's, the gripper its last joint) with the tool riding its apple's predicted motion:
        ``motion(s)`` is the apple's centre (3,) ``s`` s into the plan, ``closes`` s into it the fingers meet the
        apple. Over the straight approach the tool takes on the apple's motion relative to where it will be at the
        closing (smoothly, from none at the line's start to all of it where the grasp begins), so the apple lies in
        the tool's frame as a still one does, and after the closing it comes back onto the plan by the lift's
        end. Where all of the motion would break a joint limit, the largest of ``shares`` that keeps them is taken
        (``extra['ride_share']``). The plan as it was when it has no straight approach, the apple does not move, or
        every share would break a limit (its ``extra['rides']`` says which it got)."""
        start, grasp = plan.extra.get('grasp_start'), plan.extra.get('grasp_end')
        line, lift = (next((s for s in plan.segments if s.label == label), None) for label in RIDDEN[1:])
        unchanged = replace(plan, extra={**plan.extra, 'rides': False})
        if line is None or lift is None or not line.start < start <= closes <= grasp:
            return unchanged
        stop = lift.start + lift.duration
        begin = max(line.start - RIDE_RAMP, 0.0)
        n = max(int(np.ceil((stop - begin) / self.planner.settings.sample_period)), 4) + 1
        t = np.linspace(begin, stop, n)
        # The share of the apple's motion the tool takes on: none at first, all of it from the grasp's start to the
        # closing; the apple then held, the tool comes to rest back on the plan by the lift's end.
        before = t < closes
        w = _smoothstep(np.clip((t[before] - begin) / (start - begin), 0.0, 1.0))
        at = np.asarray(motion(closes), float)
        offset = np.zeros((n, 3))
        offset[before] = w[:, None] * (np.array([motion(s) for s in t[before]]) - at)
        h, zero = 1e-3, np.zeros(3)
        v = (np.asarray(motion(closes + h)) - np.asarray(motion(closes - h))) / (2 * h)
        a = (np.asarray(motion(closes + h)) - 2 * at + np.asarray(motion(closes - h))) / h ** 2
        back = trajectory.hermite_coeffs(zero, v, a, zero, zero, zero, stop - closes)     # (3, 6)
        offset[~before] = ((t[~before] - closes)[:, None] ** np.arange(6)) @ back.T
        if np.abs(offset).max() < 1e-6:
            return unchanged
        q = plan.trajectory.sample(t)[0]
        for share in shares:
            ridden = self._ridden(plan, t, q, share * offset)
            if ridden is not None:
                return replace(plan, trajectory=ridden, extra={**plan.extra, 'rides': True, 'ride_share': share})
        return unchanged

    def _ridden(self, plan, t, q, offset):
        """``plan``'s trajectory with the tool moved by ``offset`` (n, 3) at times ``t`` (its joints ``q`` there), or
        None where that breaks a joint limit."""
        dof = self.arm.dof
        poses = self.arm.fk(q[:, :dof])
        poses[:, :3, 3] += offset
        q_ride, ok, _ = self.arm.ik_batch(poses, q[:, :dof])
        if not ok.all() or np.abs(q_ride - q[:, :dof]).max() > self.planner.settings.max_joint_step:
            return None
        delta = np.zeros_like(q)
        delta[1:-1, :dof] = (q_ride - q[:, :dof])[1:-1]           # (the ends are on the plan)
        parts = [trajectory.quintic_via(delta, np.diff(t))]
        if t[0] > 0.0:
            parts.insert(0, trajectory.hold(0.0 * delta[0], t[0]))
        if t[-1] < plan.duration:
            parts.append(trajectory.hold(0.0 * delta[0], plan.duration - t[-1]))
        both = trajectory.stack([plan.trajectory, trajectory.concatenate(parts)])
        k = q.shape[1]
        ridden = trajectory.PiecewisePolynomial(both.breaks, both.coeffs[:, :, :k] + both.coeffs[:, :, k:])
        try:
            self.planner.check_limits(trajectory.PiecewisePolynomial(ridden.breaks, ridden.coeffs[:, :, :dof]),
                                      'riding the apple')
        except Unreachable:
            return None
        return ridden

    def back_off(self, start):
        """From ``start`` (q, qd, qdd; braking first if it moves) home to P0 at rest: a pick that gives up. The plan
        has no gripper column; Blocked naming a contact on the way."""
        stop, q_rest = self.planner.come_to_rest(start)
        method = self.s.approach_method
        home = self.planner.joint_move(q_rest, np.asarray(self.s.home_positions, float), method)
        plan = self.planner.join(([('brake', 'quintic', stop)] if stop is not None else []) +
                                 [('P0 back off', method, home)], method)
        contact = None if self.checker is None else self.checker.check(plan.trajectory)
        if contact is not None:
            raise approaches.Blocked(f'the way back home hits {contact}')
        return plan

    def _with_gripper(self, parts, cart, gripper_start):
        """The Plan of the parts ``(label, method, traj)``, the gripper's opening as its last joint."""
        plan = self.planner.join(parts, 'pick', cart)
        gripper, events = self._gripper(plan, gripper_start)
        whole = trajectory.stack([plan.trajectory, gripper])
        return Plan(whole, 'pick', plan.segments, plan.cartesian, self.arm.joint_names + (gripper_column(self.arm),),
                    events)

    def _home_from_box(self, start, through=None, mover=None):
        """``(label, method, traj, path)`` of each part from rest in the box back home: straight up out of
        the box (the way in, reversed), flowing into the move home, or (without blends) through P4;
        ``through``: joint waypoints of the move home (a detour); ``mover``: the move home's planner (default the
        cycle's)."""
        pl, s = mover or self.planner, self.s
        home = np.asarray(s.home_positions, float)
        q_box, q_top, rise_line = self._out_of_the_box(start)
        if not s.blend:
            return [('P0 back home', s.transfer_method, pl.via(np.array([q_box, q_top, *(through or []), home]),
                                                               s.transfer_method), None)]

        def home_from(rise):
            v0, a0 = rise.end_state()[1:]
            if through:
                return self._detour([rise.end_state()[0], *through, home], (v0, a0), None, pl)
            return pl.joint_move(rise.end_state()[0], home, 'optimal', v0=v0, a0=a0)
        moved, (traj, path) = self._quickest(BLEND_SPEEDS, rise_line, home_from)
        return [('P4 out of the box', 'line', traj, path), ('P0 back home', s.transfer_method, moved, None)]

    def _out_of_the_box(self, start):
        """``(q, q_top, rise_line)`` for a motion that starts at rest in the box: the joints there, at
        the height of P4 (less ``box_blend_radius``) straight above, and ``rise_line(f, rest)``, the line
        up to there, left at speed fraction ``f``."""
        q, qd, qdd = (np.asarray(x, float) for x in self.planner.check_start(start))
        if np.abs(qd).max() > 1e-9 or np.abs(qdd).max() > 1e-9:
            raise ValueError('a cycle from the box starts at rest there (where the cycle before it ended)')
        T_box = self.arm.fk(q)
        T_top = T_box.copy()
        T_top[2, 3] += self.s.box_drop_height - self.s.box_blend_radius
        try:
            q_top = self.arm.check_reachable(T_top, seed=q)
        except Unreachable as exc:
            raise Unreachable(f'P4 (above the box), rising out of it: {exc}') from None
        return q, q_top, lambda f, rest: self.planner.line(q, T_box, self.arm.fk(q_top), (0.0, f), rest)

    @staticmethod
    def _quickest(speeds, cartesian, joint):
        """``(joint move, (trajectory, path))`` of the quickest pair over the blend speeds.

        ``cartesian(f, rest)`` plans the line (or arc) at speed fraction ``f`` where it
        meets the joint move (``rest``: its path from rest to rest, None for that one
        itself); ``joint(trajectory)`` plans the move that meets it. The first speed
        (rest) must work; a faster one is skipped where it cannot (entering too fast to
        stop in time, or a joint state the move cannot reach within the limits).
        """
        line = cartesian(speeds[0], None)
        best, rest = (joint(line[0]), line), line[1]
        for f in speeds[1:]:
            try:
                line = cartesian(f, rest)
                move = joint(line[0])
            except (ValueError, Unreachable):
                continue
            if move.duration + line[0].duration < best[0].duration + best[1][0].duration:
                best = (move, line)
        return best

    def _lift(self, q_apple, poses, speed, rest=None, planner=None, lift='line'):
        """The lift from the apple to P3 (``lift``: a line up or back, or an arc that also pulls back), leaving P3
        at ``speed`` (a fraction of its fastest; ``rest``: its path from rest to rest), planned by ``planner`` (None:
        the cycle's).

        With a blend radius the lift ends that far before its end (along the line or the arc)."""
        pl, r = planner or self.planner, self.s.blend_radius
        T2, mid, end = self._lift_poses(q_apple, poses, lift)
        if mid is None:
            return pl.line(q_apple, T2, end if r == 0.0 else _toward(end, T2, r), (0.0, speed), rest)
        if r > 0.0:
            arc = geometry.Arc.through(T2[:3, 3], mid[:3, 3], end[:3, 3])
            mid, end = mid.copy(), end.copy()
            mid[:3, 3] = arc.at(0.5 * (arc.length - r))[0]
            end[:3, 3] = arc.at(arc.length - r)[0]
        return pl.arc(q_apple, T2, mid, end, (0.0, speed), rest)

    def _lift_poses(self, q_apple, poses, lift):
        """``(start, through, end)`` of the whole ``lift``: the tool at the apple, the arc's middle
        (None for a line) and its end (P3 for a line)."""
        s = self.s
        T2 = self.arm.fk(q_apple)
        if lift != 'arc':
            return T2, None, poses['P3']
        mid = T2.copy()
        mid[:3, 3] += s.lift_height * ((1 - np.sqrt(0.5)) * _level_back(T2) + np.sqrt(0.5) * np.array([0, 0, 1.0]))
        return T2, mid, _lift_end(T2, 'arc', s.lift_height)

    def _top(self, q_apple, poses, lift):
        """The joints at the end of the whole ``lift`` (where the transfer would start without a blend radius)."""
        return self.arm.check_reachable(self._lift_poses(q_apple, poses, lift)[2], seed=q_apple)

    def _ik_toward(self, name, T_from, T_to, distance, seed, setting='blend_radius'):
        """The joints where the tool is ``distance`` m from ``T_from`` (the knot point ``name``) on the
        line to ``T_to``; Unreachable naming the point and the blend radius."""
        try:
            return self.arm.check_reachable(_toward(T_from, T_to, distance), seed=seed)
        except Unreachable as exc:
            raise Unreachable(f'{name} ({_LABELS[name]}) moved by {setting} {distance} m along its line: '
                              f'{exc}') from None

    def quickest_place(self, poses, q_lift, home):
        """``(poses, q4, q5)``: the key poses with P4 and P5 turned about the vertical for the quickest
        transfer from ``q_lift`` and return to ``home``, and the joints there."""
        vmax = np.where(np.isfinite(self.arm.max_velocity), self.arm.max_velocity, 1.0)
        # Every turn at once: 12 candidates in 30 degree steps, one batched IK each for P4 and P5.
        turns = _PLACE_TURNS
        P4, P5 = np.repeat(poses['P4'][None], len(turns), 0), np.repeat(poses['P5'][None], len(turns), 0)
        P4[:, :3, :3] = turns @ poses['P4'][:3, :3]
        P5[:, :3, :3] = turns @ poses['P5'][:3, :3]
        q4, ok4, _ = self.arm.ik_batch(P4, q_lift)
        q5, ok5, _ = self.arm.ik_batch(P5, np.where(ok4[:, None], q4, q_lift))
        ok = ok4 & ok5
        if not ok.any():
            raise Unreachable('P4 (above the box): no turn of the gripper about the vertical reaches the box')
        cost = np.max(np.abs(q4 - q_lift) / vmax, axis=1) + np.max(np.abs(home - q4) / vmax, axis=1)
        best = int(np.argmin(np.where(ok, cost, np.inf)))
        return {**poses, 'P4': P4[best], 'P5': P5[best]}, q4[best], q5[best]

    def _clearance(self, qa, qb):
        """The transfer's via point: halfway in joint space, the shoulder turned by ``transfer_lift`` the way that
        raises the tool."""
        mid = 0.5 * (qa + qb)
        j = self._shoulder
        rise = self.arm.jacobian(mid)[2, j]
        mid[j] += self.s.transfer_lift * (1.0 if rise >= 0.0 else -1.0)
        return np.clip(mid, self.arm.lower, self.arm.upper)

    @functools.cached_property
    def _shoulder(self):
        """The shoulder: the first joint whose axis is horizontal at the arm's zero (it lifts the arm)."""
        frames = self.arm.joint_frames(np.zeros((1, self.arm.dof)))[0]
        for j in range(self.arm.dof):
            if abs((frames[j, :3, :3] @ self.arm._axes[j])[2]) < 0.1:
                return j
        raise ValueError(f'{self.arm.name} has no joint with a horizontal axis to lift the transfer with')

    def _gripper_time(self, wanted):
        """A dwell long enough for the fingers to move within their limits (quintic peaks)."""
        names = self.arm.all_joint_names
        if self.arm.gripper_joint is None:
            return wanted
        i = names.index(self.arm.gripper_joint)
        _, _, vmax, amax = self.arm.all_limits
        travel = self.s.gripper_open - self.s.gripper_closed
        need = max(1.875 * travel / vmax[i], np.sqrt(5.78 * travel / amax[i]) if np.isfinite(amax[i]) else 0.0)
        return max(wanted, 1.02 * need)

    def _gripper(self, plan, gripper_start):
        """The finger opening over the plan: closes during the grasp dwell, opens during release.

        One quintic per segment of the plan (a hold where the fingers keep their opening),
        all built at once.
        """
        s = self.s
        g = s.gripper_open if gripper_start is None else float(gripper_start)
        ends, events = [], {}
        # What of the opening the release dwell does not take began on the line into the box (release_lead).
        release = next((seg for seg in plan.segments if seg.label == 'release'), None)
        lead = 0.0 if release is None else max(self._gripper_time(s.release_time) - release.duration, 0.0)
        for seg, after in zip(plan.segments, [*plan.segments[1:], None]):
            start, duration = g, seg.duration - (lead if after is release else 0.0)
            if seg.label == 'grasp':
                g = s.gripper_closed
                events['grasp_start'], events['grasp_end'] = seg.start, seg.start + seg.duration
            elif seg.label == 'release':
                g = s.gripper_open
                events['release_start'], events['release_end'] = seg.start - lead, seg.start + seg.duration
                duration += lead
            elif seg.label in ('brake', 'P0 home', 'P1 approach') and seg.duration >= self._gripper_time(0.0):
                g = s.gripper_open
            if duration > 1e-9:                     # (a line into the box the opening took whole)
                ends.append((start, g, duration))
        g0, g1, durations = np.array(ends).T
        coeffs = trajectory.hermite_coeffs(g0, 0.0, 0.0, g1, 0.0, 0.0, durations)
        breaks = np.concatenate(([0.0], np.cumsum(durations)))
        return trajectory.PiecewisePolynomial(breaks, coeffs[:, :, None]), events


_LABELS = {'P1': 'approach', 'P2': 'the apple', 'P3': 'lift', 'P4': 'above the box', 'P5': 'into the box'}


class _SlowPast:
    """A joint move's planner (``planner``, every attribute its own) whose jerk-limited moves run at full speed up
    to the first configuration of ``slowed.window`` and after the second (None: the move's own start or end), and
    at ``slowed.fraction`` of it between them; any other move (a method other than ``optimal``, a least duration)
    is slowed whole by ``whole``."""

    def __init__(self, planner, whole, slowed):
        self.planner, self.whole, self.slowed = planner, whole, slowed

    def __getattr__(self, name):
        return getattr(self.planner, name)

    def joint_move(self, q0, qf, method, duration=None, v0=None, a0=None, vf=None, af=None):
        if method != 'optimal' or duration:
            return self.whole.joint_move(q0, qf, method, duration, v0, a0, vf, af)
        return self.via(np.array([q0, qf]), method, (v0, a0), (vf, af))

    def via(self, qs, method, start=None, end=None):
        if method != 'optimal':
            return self.whole.via(qs, method, start, end)
        qs = [np.asarray(q, float) for q in qs]
        first, last = self.slowed.window
        i = 0 if first is None else _insert_nearest(qs, first, 0)
        k = len(qs) - 1 if last is None else _insert_nearest(qs, last, i)
        scales = tuple(self.slowed.fraction if i <= leg < k else 1.0 for leg in range(len(qs) - 1))
        return self.planner.via(np.array(qs), method, start, end, scales)


def _insert_nearest(qs, q, after):
    """Insert ``q`` into the joint path ``qs`` (a list) on the leg from point ``after`` on that it lengthens
    least; its index."""
    legs = range(after, len(qs) - 1)
    added = [np.linalg.norm(qs[j] - q) + np.linalg.norm(q - qs[j + 1]) - np.linalg.norm(qs[j + 1] - qs[j])
             for j in legs]
    j = legs[int(np.argmin(added))] + 1
    qs.insert(j, np.asarray(q, float))
    return j
