"""From goals to joint trajectories (pure core of the planner node).

:class:`Planner` turns a tool pose, a list of poses, or a 3-pose arc into a
:class:`Plan`: a joint trajectory that starts at the given state, respects the
arm's velocity and acceleration limits, and reports its tool path. It checks
reachability first (the paper's step C) and refuses with the reason.

Methods
-------
Pose goals (``method``): ``cubic``, ``quintic``, ``lspb`` (joint space, the
paper's profiles), ``optimal`` (joint space, jerk-limited and time-optimal, by
Ruckig) or ``line`` (Cartesian straight line, orientation slerped).
Path goals (``path_method``): ``via_lspb`` (Fig. 12), ``quintic_via`` or
``optimal`` (jerk-limited segments that pass the via points at speed) through
the IK of every pose, ``line`` (straight lines pose to pose, stopping at each),
or ``arc`` (3-point arc, Sec. 2.3).

With ``limit_jerk`` set, lines, arcs and quintic moves are also stretched until
every joint keeps its jerk limit; cubic and LSPB moves step their acceleration
(an unbounded jerk) and are refused then.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np

from . import geometry, trajectory
from .kinematics import Unreachable, cartesian_to_joint
from .kinematics.paths import check_joint_limits

JOINT_METHODS = ('cubic', 'quintic', 'lspb', 'optimal')
POSE_METHODS = JOINT_METHODS + ('line',)
PATH_METHODS = ('via_lspb', 'quintic_via', 'optimal', 'line', 'arc')
#: Profiles whose acceleration steps (unbounded jerk): refused when ``limit_jerk`` is set.
JERK_UNBOUNDED = ('cubic', 'lspb', 'via_lspb')
#: Jerk limit assumed for joints that have none, per second times their acceleration limit.
DEFAULT_JERK_PER_ACCEL = 10.0

#: Via-point speeds tried by the jerk-limited via timing, times the neighbouring chords' mean speed.
VIA_SPEEDS = (1.0, 1.5, 2.0)
#: A line or arc slowed to the joint limits is slowed this much more: its peaks were measured
#: at points (see paths.CHECK_STEP), and may lie a hair beyond them between.
STRETCH_TIGHT = 1.001
#: Plans use at most this fraction of the scaled limits, so that the controller's spline
#: through the 10 ms points (which can overshoot the plan by a hair) never crosses a limit.
PLAN_MARGIN = 0.98

# Peak velocity and acceleration of a unit move in unit time, for sizing durations.
_PEAKS = {'cubic': (1.5, 6.0), 'quintic': (1.875, 10.0 / np.sqrt(3.0))}


@dataclass(frozen=True)
class PlannerSettings:
    """Knobs of the planner; the node maps its ROS parameters onto these.

    Attributes
    ----------
    method, path_method : str
        Default methods for pose and path goals.
    speed_scale : float
        Fraction of the joint velocity limits used, (0, 1]; accelerations
        scale with its square.
    duration : float
        Fixed duration of a pose move, s; 0 means the shortest within limits.
    sample_period : float
        Spacing of the trajectory points, s.
    cartesian_speed, cartesian_accel : float
        Initial guesses for line and arc timing, m/s and m/s^2 (stretched when
        the joints need more time).
    cartesian_profile : str
        Time profile of the progress along lines and arcs: ``quintic`` (smooth
        ends), ``lspb``, ``cubic``, or ``optimal`` (Ruckig's time-optimal,
        jerk-limited progress within ``cartesian_speed``, ``cartesian_accel`` and
        10/s times that as jerk: about 10 % shorter lines than ``quintic`` when
        ``limit_jerk`` binds).
    max_joint_step : float
        Jump threshold of Cartesian paths, rad per sample.
    limit_jerk : bool
        Keep every segment within the joints' jerk limits too (lines, arcs and
        quintic moves are stretched; cubic and LSPB moves are refused).
    """

    method: str = 'quintic'
    path_method: str = 'via_lspb'
    speed_scale: float = 0.5
    duration: float = 0.0
    sample_period: float = 0.01
    cartesian_speed: float = 0.6
    cartesian_accel: float = 4.0
    cartesian_profile: str = 'quintic'
    max_joint_step: float = 0.25
    limit_jerk: bool = False

    def validate(self):
        if self.method not in POSE_METHODS:
            raise ValueError(f'unknown method {self.method!r}; choose one of {", ".join(POSE_METHODS)}')
        if self.path_method not in PATH_METHODS:
            raise ValueError(f'unknown path_method {self.path_method!r}; choose one of {", ".join(PATH_METHODS)}')
        if self.cartesian_profile not in geometry.PROFILES:
            raise ValueError(f'unknown cartesian_profile {self.cartesian_profile!r}; choose one of '
                             f'{", ".join(geometry.PROFILES)}')
        if not 0.0 < self.speed_scale <= 1.0:
            raise ValueError(f'speed_scale must be in (0, 1], got {self.speed_scale}')
        for name in ('sample_period', 'cartesian_speed', 'cartesian_accel', 'max_joint_step'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be > 0, got {value}')
        if not (np.isfinite(self.duration) and self.duration >= 0):
            raise ValueError(f'duration must be >= 0 s (0: shortest within limits), got {self.duration}')
        if not isinstance(self.limit_jerk, (bool, np.bool_)):
            raise ValueError(f'limit_jerk must be true or false, got {self.limit_jerk!r}')
        if self.limit_jerk:
            for name in ('method', 'path_method'):
                if getattr(self, name) in JERK_UNBOUNDED:
                    raise ValueError(f'{name} {getattr(self, name)} steps the acceleration (unbounded jerk): '
                                     'with limit_jerk choose optimal or quintic')
        return self


@dataclass(frozen=True)
class Segment:
    """One part of a plan, for reports: its label, method, start time and duration (s)."""

    label: str
    method: str
    start: float
    duration: float


@dataclass(frozen=True)
class Plan:
    """A planned motion.

    Attributes
    ----------
    trajectory : PiecewisePolynomial
        Joint trajectory from the start state, time 0 = now.
    method : str
    segments : list of Segment
    cartesian : list of (int, CartesianPath)
        The Cartesian parts (lines, arcs): segment index and requested path, for
        measuring the tool's deviation.
    joint_names : tuple of str
        Joint order of the trajectory when it is not just the arm's (the pick
        cycle appends the gripper).
    extra : dict
        Event times and figures for reports (grasp and release times).
    """

    trajectory: trajectory.PiecewisePolynomial
    method: str
    segments: list = field(default_factory=list)
    cartesian: list = field(default_factory=list)
    joint_names: tuple = ()
    extra: dict = field(default_factory=dict)

    @property
    def duration(self):
        return self.trajectory.duration

    def samples(self, period):
        """``t, q, qd, qdd`` every ``period`` s, the last point exactly at the end."""
        n = int(np.floor(self.duration / period + 1e-9))
        t = np.arange(n + 1) * period
        if self.duration - t[-1] > 1e-9:
            t = np.append(t, self.duration)
        return (t, *self.trajectory.sample(t))

    def summary(self, period=0.01):
        """Duration, peak |velocity| and |acceleration| per joint."""
        _, _, qd, qdd = self.samples(period / 4)
        return {'method': self.method, 'duration': self.duration,
                'peak_velocity': np.abs(qd).max(axis=0), 'peak_acceleration': np.abs(qdd).max(axis=0)}


def _check_times(traj):
    """Where the limits of ``traj`` (its own clock starting at 0) are checked: every 2.5 ms, at
    least 50 times; for a trajectory of parabolas (LSPB: each piece of degree <= 2), exactly
    where its extremes lie instead: the breaks (its velocity is linear in each piece), the
    middle of each piece (its constant acceleration; at a break the piece that ends there
    answers) and where a joint turns inside a piece (its position's extreme there)."""
    b, c = traj.breaks, traj.coeffs
    if c[:, 3:].any():
        return np.linspace(0.0, traj.duration, max(50, int(traj.duration / 0.0025)))
    span = b[1:] - b[:-1]
    v0 = c[:, 1]
    piece, joint = np.nonzero(v0 * (v0 + 2.0 * c[:, 2] * span[:, None]) < 0.0)    # qd changes sign
    turns = b[piece] - v0[piece, joint] / (2.0 * c[piece, 2, joint])
    return np.sort(np.concatenate((b, b[:-1] + 0.5 * span, turns)))


def feasible_start(arm, q, qd, qdd):
    """An extrapolated reference state held within the limits, as the controller's reference is.

    Carried on too far, a constant acceleration crosses a limit; no plan can start from
    such a state and keep the limits. A joint at a position limit stops there; one at
    its velocity limit stops accelerating beyond it; accelerations are clipped. (The
    controller's lead-in absorbs the small difference from its real reference.)
    """
    vmax = arm.max_velocity
    q1, qd1, qdd1 = trajectory.held_within_limits(q, qd, qdd, arm.lower, arm.upper, vmax, arm.max_acceleration)
    # Speeding up, a joint gains a^2 / 2j more speed before the jerk limit lets its
    # acceleration reach zero: no more than it has left below its speed limit.
    room = np.sqrt(2.0 * _full_jerk(arm) * np.maximum(vmax - np.abs(qd1), 0.0))
    speeding_up = qdd1 * qd1 > 0
    qdd1 = np.where(speeding_up, np.clip(qdd1, -room, room), qdd1)
    return q1, qd1, qdd1


def _read_only(a):
    a.flags.writeable = False
    return a


def _full_jerk(arm):
    """The arm's jerk limits, DEFAULT_JERK_PER_ACCEL times the acceleration limit where none is given."""
    a = np.where(np.isfinite(arm.max_acceleration), arm.max_acceleration, 2.0)
    return np.where(np.isfinite(arm.max_jerk), arm.max_jerk, DEFAULT_JERK_PER_ACCEL * a)


class Planner:
    """Plans for one arm; see the module docstring for the methods."""

    def __init__(self, arm, settings=PlannerSettings()):
        self.arm = arm
        self.settings = settings.validate()
        trajectory.use_compiled_kernels()        # a plan samples its splines many times

    def with_settings(self, **changes):
        return Planner(self.arm, replace(self.settings, **changes))

    # -- limits and durations -----------------------------------------------------
    # The scaled limits, computed once: the settings are frozen and the arm's limits read-only
    # (a pick cycle reads them about 30 times).
    @functools.cached_property
    def _vmax(self):
        v = np.where(np.isfinite(self.arm.max_velocity), self.arm.max_velocity, 1.0)
        return _read_only(v * self.settings.speed_scale * PLAN_MARGIN)

    @functools.cached_property
    def _amax(self):
        a = np.where(np.isfinite(self.arm.max_acceleration), self.arm.max_acceleration, 2.0)
        return _read_only(a * (self.settings.speed_scale ** 2) * PLAN_MARGIN)

    @functools.cached_property
    def _jmax(self):
        return _read_only(_full_jerk(self.arm) * (self.settings.speed_scale ** 3) * PLAN_MARGIN)

    def shortest_duration(self, q0, qf, method):
        """The shortest time in which every joint makes its move within the scaled limits, s."""
        return float(self._shortest_durations(np.array((q0, qf), float), method)[0])

    def _shortest_durations(self, qs, method):
        """:meth:`shortest_duration` of each move between consecutive configurations ``qs``
        (m + 1, n), shape (m,)."""
        h = np.abs(np.diff(qs, axis=0))
        v, a = self._vmax, self._amax
        if method == 'lspb':
            cruise = h > v**2 / a
            t = np.where(cruise, h / v + v / a, 2.0 * np.sqrt(h / a))
        else:
            kv, ka = _PEAKS[method]
            t = np.maximum(kv * h / v, np.sqrt(ka * h / a))
        return np.maximum(t.max(axis=1), self.settings.sample_period)

    def _check(self, traj, label):
        t = _check_times(traj)
        q, qd, qdd = traj.sample(t)
        try:
            check_joint_limits(self.arm, t, q, qd, qdd, slack=1e-6)
            if self.settings.limit_jerk:
                self._check_jerk(traj, t)
        except Unreachable as exc:
            raise Unreachable(f'{label}: {exc}') from None

    def _limit_use(self, traj):
        """How far ``traj`` goes into the scaled limits: the largest |qd| / vmax and sqrt(|qdd| / amax)
        (stretched that many times, it reaches them)."""
        t = np.linspace(0.0, traj.duration, max(50, int(traj.duration / 0.0025)))
        _, qd, qdd = traj.sample(t)
        return max(float(np.max(np.abs(qd) / self._vmax)), float(np.sqrt(np.max(np.abs(qdd) / self._amax))))

    def _jerk_ratio(self, traj, t):
        """Largest |jerk| over the scaled jerk limit along ``traj`` at times ``t``."""
        jerk = np.abs(traj.jerk(t))[:, :self.arm.dof]
        return float(np.max(jerk / self._jmax)) if jerk.size else 0.0

    def _check_jerk(self, traj, t):
        over = self._jerk_ratio(traj, t)
        if over > 1.0 / PLAN_MARGIN + 1e-6:
            raise Unreachable(f'jerk limit broken: {over * PLAN_MARGIN:.2f} times the limit; slow the motion down')

    # -- the start ----------------------------------------------------------------------
    def _start(self, start):
        """``start = (q, qd, qdd)`` as three finite arrays of one value per joint (a velocity or an
        acceleration given as one number holds for every joint), else ValueError."""
        try:
            q, qd, qdd = start
        except (TypeError, ValueError):
            raise ValueError('start must be (q, qd, qdd): positions, velocities, accelerations') from None
        out = []
        for name, x in (('start position', q), ('start velocity', qd), ('start acceleration', qdd)):
            try:
                arr = np.asarray(x, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f'{name} must be numbers, one per joint') from None
            if arr.ndim == 0 and name != 'start position':
                arr = np.full(self.arm.dof, float(arr))
            if arr.shape != (self.arm.dof,):
                raise ValueError(f'{name} must have {self.arm.dof} values (one per joint), got shape {arr.shape}')
            out.append(self.arm.check_joints(arr, name))
        return tuple(out)

    def _from_rest(self, start):
        """A braking segment when the start state moves (None at rest), and the rest state."""
        q, qd, qdd = self._start(start)
        if np.abs(qd).max() < 1e-4 and np.abs(qdd).max() < 1e-3:
            return None, q
        vmax = np.where(np.isfinite(self.arm.max_velocity), self.arm.max_velocity, np.inf)
        amax = np.where(np.isfinite(self.arm.max_acceleration), self.arm.max_acceleration, np.inf)
        # Ruckig's time-optimal, jerk-limited stop keeps the velocity and acceleration limits
        # whenever any stop can.
        try:
            stop = trajectory.time_optimal_stop(q, qd, qdd, np.minimum(vmax, 1e3), np.minimum(amax, 1e4),
                                                np.minimum(_full_jerk(self.arm), 1e5))
            p, v, a = stop.sample(np.linspace(0.0, stop.duration, 201))
            if (np.abs(v) <= vmax + 1e-9).all() and (np.abs(a) <= amax + 1e-9).all() and \
                    self.arm.within_limits(p).all():
                return stop, stop.end_state()[0]
        except ValueError:
            pass
        # Else the shortest of a few quintic stops that keeps the limits (a start already
        # decelerating hard needs more time than its speed alone says); none does: the first,
        # unless it leaves a position limit (no plan from this start could keep it).
        first = None
        for least in (0.05, 0.1, 0.2, 0.4):
            stop = trajectory.brake(q, qd, qdd, self.arm.max_acceleration, min_duration=least)
            if first is None:
                first = stop
            p, v, a = stop.sample(np.linspace(0.0, stop.duration, 101))
            if (np.abs(v) <= np.maximum(vmax, np.abs(qd)) + 1e-9).all() and \
                    (np.abs(a) <= np.maximum(amax, np.abs(qdd)) + 1e-9).all() and self.arm.within_limits(p).all():
                break
        else:
            stop = first
            self._check_stops_within_position_limits(q, qd, stop)
        return stop, stop.end_state()[0]

    def _check_stops_within_position_limits(self, q, qd, stop):
        """Unreachable, naming the joint, when the stop from the start passes a position limit."""
        p = stop.sample(np.linspace(0.0, stop.duration, 101))[0]
        arm = self.arm
        beyond = (p < arm.lower - 1e-9) | (p > arm.upper + 1e-9)
        if beyond.any():
            j = int(np.flatnonzero(beyond.any(axis=0))[0])
            upper = bool((p[:, j] > arm.upper[j] + 1e-9).any())
            reach = p[:, j].max() if upper else p[:, j].min()
            limit = arm.upper[j] if upper else arm.lower[j]
            raise Unreachable(f'{arm.joint_names[j]} moves at {qd[j]:.3g} rad/s from {q[j]:.4g} rad toward its '
                              f'limit {limit:.4g} rad and cannot stop before it (a stop within the acceleration '
                              f'limit reaches {reach:.4g} rad): no plan from this motion keeps the limit')

    def _join(self, parts, method, cartesian=()):
        """Concatenate (label, method, traj) parts into a Plan with its segment table."""
        segments, t = [], 0.0
        for label, m, traj in parts:
            segments.append(Segment(label, m, t, traj.duration))
            t += traj.duration
        whole = trajectory.concatenate([p[2] for p in parts])
        return Plan(whole, method, segments, list(cartesian), self.arm.joint_names)

    # -- pose goals -----------------------------------------------------------------------
    def joint_move(self, q0, qf, method, duration=None, v0=None, a0=None, vf=None, af=None):
        """A joint-space move between configurations within the limits (``optimal`` only:
        to a moving target state ``vf``, ``af``)."""
        if method not in JOINT_METHODS:
            raise ValueError(f'unknown joint method {method!r}; choose one of {", ".join(JOINT_METHODS)}')
        if self.settings.limit_jerk and method in JERK_UNBOUNDED:
            raise ValueError(f'{method} moves step the acceleration (unbounded jerk): with limit_jerk choose '
                             'optimal or quintic')
        if method == 'optimal':
            traj = trajectory.time_optimal(q0, qf, self._vmax, self._amax, self._jmax, v0, a0, vf, af,
                                           min_duration=duration or self.settings.duration or 0.0)
            self._check(traj, 'optimal move')
            return traj
        if vf is not None or af is not None:
            raise ValueError('only optimal moves end at a moving target state')
        T = duration or self.settings.duration or self.shortest_duration(q0, qf, method)
        if method == 'cubic':
            traj = trajectory.cubic(q0, qf, T, 0.0 if v0 is None else v0)
        elif method == 'quintic':
            traj = trajectory.quintic(q0, qf, T, 0.0 if v0 is None else v0, 0.0,
                                      0.0 if a0 is None else a0)
        else:
            accel = np.maximum(self._amax, trajectory.min_lspb_accel(q0, qf, T) * (1 + 1e-9))
            traj = trajectory.lspb(q0, qf, T, accel)
        self._check(traj, f'{method} move')
        return traj

    def plan_pose(self, start, T_goal, method=None):
        """Move the tool to ``T_goal`` (4x4 in the base frame) from ``start = (q, qd, qdd)``."""
        method = method or self.settings.method
        if method not in POSE_METHODS:
            raise ValueError(f'unknown method {method!r}; choose one of {", ".join(POSE_METHODS)}')
        q, qd, qdd = start = self._start(start)
        if method == 'line':
            stop, q_rest = self._from_rest(start)
            traj, path = self.line(q_rest, self.arm.fk(q_rest), T_goal)
            parts = ([('brake', 'quintic', stop)] if stop is not None else []) + [('line', 'line', traj)]
            cart = [(len(parts) - 1, path)]
            return self._join(parts, 'line', cart)
        q_goal = self.arm.check_reachable(T_goal, seed=q)
        if method in ('cubic', 'quintic', 'optimal'):
            try:
                traj = self.joint_move(q, q_goal, method, v0=qd, a0=qdd if method != 'cubic' else None)
                return self._join([('move', method, traj)], method)
            except Unreachable:
                if self._from_rest(start)[0] is None:
                    raise
                # Carried on from this motion the move would cross a limit (an overshoot near a
                # joint limit, or a start already near the speed limit): brake first, then move.
        stop, q_rest = self._from_rest(start)
        parts = ([('brake', 'quintic', stop)] if stop is not None else [])
        parts.append(('move', method, self.joint_move(q_rest, q_goal, method)))
        return self._join(parts, method)

    # -- Cartesian lines and arcs ----------------------------------------------------------
    def _timed_cartesian(self, curve, q0, orientations, keys=None, ends=(0.0, 0.0), rest=None):
        """Time a curve: start from the Cartesian guess, stretch until the joints keep their limits.

        ``ends``: the progress speed at the start and at the end, as fractions of the
        fastest progress that keeps the joint limits from rest to rest (``optimal``
        profile only): a line entered or left at speed, blended with the joint move
        before or after it. The joint trajectory then starts (ends) with the
        velocity and acceleration of the moving path. ``rest``: the same curve's
        rest-to-rest path, if already timed (else timed here first).
        """
        s = self.settings
        length = curve.length
        limits = None
        if s.cartesian_profile == 'optimal':
            # The tool's speed and acceleration guesses, and a jerk of DEFAULT_JERK_PER_ACCEL times the
            # acceleration, as limits of the progress (1/s^k): the time-optimal shape within them.
            limits = (np.array([s.cartesian_speed, s.cartesian_accel, DEFAULT_JERK_PER_ACCEL * s.cartesian_accel])
                      / max(length, 1e-9))
            guess = max(geometry.optimal_progress(limits).duration, 0.2)
        else:
            guess = max(1.875 * length / s.cartesian_speed, np.sqrt(5.78 * length / s.cartesian_accel), 0.2)
        moving = tuple(float(f) > 0.0 for f in ends)
        if any(moving):
            if s.cartesian_profile != 'optimal' or s.duration:
                raise ValueError('a line or arc entered or left at speed needs cartesian_profile optimal and no '
                                 'fixed duration')
            if not all(0.0 <= float(f) < 1.0 for f in ends):
                raise ValueError(f'end speeds must be fractions in [0, 1), got {list(ends)}')
            # The rest-to-rest timing gives the progress limits that keep the joints' (its
            # profile stretched k times is the time-optimal one within limits / k, / k^2, / k^3).
            if rest is None:
                _, rest = self._timed_cartesian(curve, q0, orientations, keys)
            k = rest.duration / geometry.optimal_progress(limits).duration
            limits = limits / np.array([k, k * k, k ** 3])
            shape = trajectory.time_optimal([0.0], [1.0], *limits, v0=[ends[0] * limits[0]],
                                            vf=[ends[1] * limits[0]])
            if shape.sample(np.linspace(0.0, shape.duration, 200))[1].min() < -1e-9:
                raise Unreachable(f'entered at {ends[0]:.0%} of its speed the path overshoots its end')
            T = shape.duration
        else:
            shape = None
            T = s.duration or guess
        if shape is None:
            path = geometry.CartesianPath.timed(curve, T, s.cartesian_profile, orientations=orientations,
                                                keys=keys, limits=limits)
        else:
            path = geometry.CartesianPath(curve, shape.stretched(T / shape.duration), orientations, keys)
        jp = cartesian_to_joint(self.arm, path, q0, dt=s.sample_period, max_joint_step=s.max_joint_step,
                                check_limits=False, free_ends=moving)
        traj = jp.trajectory
        over = max(float(np.max(jp.peak_velocity / self._vmax)),
                   float(np.sqrt(np.max(jp.peak_acceleration / self._amax))))
        if s.limit_jerk:
            over = max(over, self._jerk_ratio(traj, np.linspace(0.0, T, max(50, int(T / 0.0025)))) ** (1.0 / 3.0))
        # Slowed down by k, the tool passes the same poses, so the joints pass the same
        # configurations: the joint path is this one stretched in time, its speeds divided by
        # k, accelerations by k^2, jerks by k^3 (the spline through the IK samples stretches
        # with them). The IK is solved once; its samples end up k * sample_period apart, and
        # the points the conversion checked are checked again, stretched the same way.
        t_check, q_check, qd_check, qdd_check = jp.checked
        stretch = 1.0
        for _ in range(6):
            if over <= 1.0:
                # The peaks were taken at these points, within the planner's (scaled) limits: what
                # can still fail is a position limit, which no stretch mends.
                check_joint_limits(self.arm, t_check * stretch, q_check, qd_check / stretch,
                                   qdd_check / stretch ** 2)
                return traj, path
            if s.duration:
                raise Unreachable(f'the path needs {over:.2f} times the allowed joint speed in the '
                                  f'fixed duration {s.duration} s')
            k = over * STRETCH_TIGHT
            traj, path = traj.stretched(k), path.stretched(k)
            stretch *= k
            over = over / k
        raise Unreachable('could not time the Cartesian path within the joint limits')

    def line(self, q0, T_start, T_goal, ends=(0.0, 0.0), rest=None):
        """Straight tool line from ``T_start`` to ``T_goal`` with slerped orientation
        (``ends``, ``rest``: see :meth:`_timed_cartesian`)."""
        self.arm.check_reachable(T_goal, seed=q0)
        line = geometry.Line(T_start[:3, 3], T_goal[:3, 3])
        rots = np.stack([T_start[:3, :3], T_goal[:3, :3]])
        if self.arm.dof < 6:
            rots = None
        return self._timed_cartesian(line, q0, rots, ends=ends, rest=rest)

    def arc(self, q0, T1, T2, T3, ends=(0.0, 0.0), rest=None):
        """Tool arc from ``T1`` (the current pose) through ``T2`` to ``T3`` (Sec. 2.3)
        (``ends``, ``rest``: see :meth:`_timed_cartesian`)."""
        for T in (T2, T3):
            self.arm.check_reachable(T, seed=q0)
        curve = geometry.Arc.through(T1[:3, 3], T2[:3, 3], T3[:3, 3])
        rots = None
        keys = None
        if self.arm.dof >= 6:
            rots = np.stack([T1[:3, :3], T2[:3, :3], T3[:3, :3]])
            # The key of p2 is its arc-length fraction along the arc.
            p = curve.points(2001)
            keys = [0.0, float(np.argmin(np.linalg.norm(p - T2[:3, 3], axis=1)) / 2000), 1.0]
            keys[1] = min(max(keys[1], 1e-3), 1 - 1e-3)
        return self._timed_cartesian(curve, q0, rots, keys, ends, rest)

    # -- path goals -------------------------------------------------------------------------
    def plan_path(self, start, poses, method=None):
        """Pass through ``poses`` (list of 4x4) from ``start = (q, qd, qdd)``."""
        method = method or self.settings.path_method
        if method not in PATH_METHODS:
            raise ValueError(f'unknown path method {method!r}; choose one of {", ".join(PATH_METHODS)}')
        poses = list(poses)
        if not poses:
            raise ValueError('the path has no poses')
        stop, q = self._from_rest(start)
        parts = [('brake', 'quintic', stop)] if stop is not None else []
        cart = []
        if method in ('via_lspb', 'quintic_via', 'optimal'):
            qs = [q]
            for i, T in enumerate(poses):
                try:
                    qs.append(self.arm.check_reachable(T, seed=qs[-1]))
                except Unreachable as exc:
                    raise Unreachable(f'pose {i}: {exc}') from None
            parts.append(('via points', method, self._via(np.array(qs), method)))
        elif method == 'line':
            T_prev = self.arm.fk(q)
            for i, T in enumerate(poses):
                try:
                    traj, path = self.line(q, T_prev, T)
                except Unreachable as exc:
                    raise Unreachable(f'line to pose {i}: {exc}') from None
                parts.append((f'line {i}', 'line', traj))
                cart.append((len(parts) - 1, path))
                q, T_prev = traj.end_state()[0], T
        else:
            if len(poses) not in (2, 3):
                raise ValueError(f'an arc needs 2 poses (through, end; it starts at the tool) or 3 '
                                 f'(start, through, end), got {len(poses)}')
            if len(poses) == 3:
                q_first = self.arm.check_reachable(poses[0], seed=q)
                parts.append(('to arc start', 'quintic', self.joint_move(q, q_first, 'quintic')))
                q = q_first
            T1 = self.arm.fk(q)
            traj, path = self.arc(q, T1, poses[-2], poses[-1])
            parts.append(('arc', 'arc', traj))
            cart.append((len(parts) - 1, path))
        return self._join(parts, method, cart)

    def _via(self, qs, method, start=None, end=None):
        """Joint via points timed from the limits, stretched until feasible.

        Each segment starts from the rest-to-rest time of its slowest joint (60 % of
        it for via-point LSPB, which passes its via points at speed); the durations then
        grow by 4 % until the blends fit and the scaled limits hold (a quintic spline
        too fast for them stretches by exactly the factor it needs). ``start`` and
        ``end``: ``(velocity, acceleration)`` at the first and last point, ``optimal`` only
        (default at rest).
        """
        if method == 'optimal':
            return self._optimal_via(np.asarray(qs, float), start, end)
        if start is not None or end is not None:
            raise ValueError('only optimal via points start or end moving')
        profile = 'lspb' if method == 'via_lspb' else 'quintic'
        durations = self._shortest_durations(qs, profile)
        if method == 'via_lspb' and len(durations) > 1:
            # Interior via points are passed at speed, not stopped at: start from 60 %, but not
            # below the timing whose lines keep the speed limit v. An interior line runs at
            # dq / T. The first and last, which blend from and to rest at a, run at
            # 2 dq / (T + sqrt(T^2 - 2 dq / a)): within v from T = dq / v + v / 2a on, and from
            # their shortest time, T = sqrt(2 dq / a), where dq < v^2 / 2a.
            dq = np.abs(np.diff(qs, axis=0))
            v, a = self._vmax, self._amax
            need = np.max(dq / v, axis=1)
            ends = dq[[0, -1]]
            need[[0, -1]] = np.max(np.where(ends >= v * v / (2.0 * a), ends / v + v / (2.0 * a),
                                            np.sqrt(2.0 * ends / a)), axis=1)
            durations = np.maximum(0.6 * durations, need)
        durations = np.maximum(durations, 2 * self.settings.sample_period)
        last = None
        for _ in range(60):
            try:
                if method == 'via_lspb':
                    # The timing alone first (microseconds): the trajectory is built once its blends
                    # fit and its lines keep the scaled speed limit (its fastest speeds are its lines':
                    # the blends join them). A line ending in a blend from rest slows far more than
                    # its stretch near the shortest timing, hence small steps.
                    timing = trajectory.via_lspb_timing(qs, durations, self._amax)
                    if (np.abs(timing[1]) > self._vmax * (1.0 + 1e-9)).any():
                        raise ValueError('a line is faster than the scaled velocity limit')
                    traj = trajectory.via_lspb(qs, durations, self._amax, timing)
                else:
                    # The spline through the points stretched k times: speeds / k, accelerations / k^2.
                    traj = trajectory.quintic_via(qs, durations)
                    over = self._limit_use(traj)
                    if over > 1.0:
                        durations = durations * (over * STRETCH_TIGHT)
                        continue
                self._check(traj, method)
                return traj
            except ValueError as exc:       # blends do not fit, or a limit is broken: slow down
                last = str(exc)             # (the exception itself, its traceback holding this frame, is a cycle)
                durations = durations * 1.04
        raise Unreachable(f'{method}: no timing within the joint limits ({last})')

    def _optimal_via(self, qs, start=None, end=None):
        """Jerk-limited, time-optimal segments through via points, passed at speed.

        A joint passes a via point at a multiple of the mean of its neighbouring
        chords' speeds (chords timed rest to rest) where both go the same way, and
        stops where it turns back; each segment is then Ruckig's fastest move
        between those states. The multiple is the fastest of VIA_SPEEDS (the mean
        itself is often too slow: a transfer's via point cost 0.1 s over the direct
        move at 1x, nothing at 2x).
        """
        (v0, a0), (vf, af) = start or (None, None), end or (None, None)
        if len(qs) == 2:
            return self.joint_move(qs[0], qs[1], 'optimal', v0=v0, a0=a0, vf=vf, af=af)
        chords = self._shortest_durations(qs, 'lspb')
        slopes = np.diff(qs, axis=0) / chords[:, None]
        onward = np.sign(slopes[:-1]) == np.sign(slopes[1:])
        mean = np.where(onward, 0.5 * (slopes[:-1] + slopes[1:]), 0.0)
        best, error = None, None
        for scale in VIA_SPEEDS:
            v = np.zeros_like(qs)
            v[1:-1] = np.clip(scale * mean, -self._vmax, self._vmax)
            a = np.zeros_like(qs)
            for i, vi, ai in ((0, v0, a0), (-1, vf, af)):
                v[i], a[i] = (0.0 if vi is None else vi), (0.0 if ai is None else ai)
            try:
                parts = [trajectory.time_optimal(qs[i], qs[i + 1], self._vmax, self._amax, self._jmax, v[i], a[i],
                                                 v[i + 1], a[i + 1]) for i in range(len(qs) - 1)]
            except ValueError as exc:
                error = str(exc)            # (not the exception: with its traceback, a cycle)
                continue
            if best is None or sum(p.duration for p in parts) < sum(p.duration for p in best):
                best = parts
        if best is None:
            raise ValueError(error)
        traj = trajectory.concatenate(best)
        self._check(traj, 'optimal via points')
        return traj
