"""What the planner is asked and what it answers: its settings and its plans."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import geometry
from ..methods import JOINT_METHODS, PATH_METHODS, POSE_METHODS  # noqa: F401 - re-exported with the settings
from ..trajectory import PiecewisePolynomial

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
        Spacing of the samples a plan is made and checked at (a Cartesian path's IK, the shortest segment), s.
    point_period : float
        Longest time between two points of a plan as it is sent (every break of the plan is a point too, so a
        controller that runs quintics through the points runs it exactly), s.
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
    point_period: float = 0.01
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
        for name in ('sample_period', 'point_period', 'cartesian_speed', 'cartesian_accel', 'max_joint_step'):
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

    trajectory: PiecewisePolynomial
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
