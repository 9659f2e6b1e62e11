"""The trajectory controller's logic, with no ROS in it.

:class:`ControllerCore` holds the active trajectory on the controller's clock,
produces the reference at every tick, validates new trajectories, splices them
onto the current reference (no jump), monitors tracking against tolerances,
and runs the feedback watchdog. The node only feeds it messages and the clock
and publishes what it returns.

Times are seconds on one clock (the node's ROS clock).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from picking_core.trajectory import PiecewisePolynomial

#: Shortest lead-in from the current reference to a new trajectory's first point, s.
MIN_LEAD = 0.02
#: Lead-ins tried in turn when a shorter one would break a limit (a trajectory that came late), s.
LEADS = (MIN_LEAD, 0.05, 0.1, 0.2)


class Mode(str, enum.Enum):
    """What the controller is doing: waiting for its first feedback, holding a position, moving
    along a trajectory, or holding after a fault (a tolerance violated) until a new trajectory."""

    WAITING = 'waiting'
    HOLDING = 'holding'
    MOVING = 'moving'
    FAULT = 'fault'


class LateTrajectory(ValueError):
    """A trajectory that came too late to run as sent: it ends before it could take over, or the
    points due by then cannot be caught up on (too far from the reference, or only beyond a
    limit), or it was planned from a reference the controller no longer follows (its first point
    is not where the reference will be, and the lead-in from there breaks a limit). Its sender
    may plan it again; a trajectory rejected otherwise is at fault itself."""


@dataclass(frozen=True)
class Prepared:
    """A validated trajectory, ready to take over at ``t_splice`` (see :meth:`ControllerCore.prepare`)."""

    traj: PiecewisePolynomial
    t_splice: float
    version: int
    accepted: Event
    lead_in: float = 0.0                 # s: the lead-in from the reference to the first point
    goal: object = None                  # the action goal it runs for (None: a topic's trajectory)
    tolerances: object = None            # its goals.JointTolerances (None: the defaults)
    origin: float = 0.0                  # clock time of its points' time_from_start 0 (its header stamp)


@dataclass(frozen=True)
class Tolerances:
    """Tracking tolerances (rad, s), one value for every joint or one per joint."""

    path: float = 0.1                    # largest |measured - reference| while moving
    goal: float = 0.005                  # at the end
    goal_time: float = 2.0               # s after the end to get within ``goal``
    stopped_velocity: float = 0.02       # rad/s, "at rest" at the goal
    state_timeout: float = 0.5           # s without joint_states before "feedback lost"


@dataclass
class Event:
    """Something the node reports on ``controller_status``."""

    level: str                           # 'OK', 'WARN' or 'ERROR' (picking_common's Level names)
    message: str
    values: dict = field(default_factory=dict)
    goal: object = None                  # the goal this event ends (with ``outcome``), if any
    outcome: object = None               # its goals.Outcome
