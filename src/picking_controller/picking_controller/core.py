"""The trajectory controller's logic, with no ROS in it.

:class:`ControllerCore` holds the active trajectory on the controller's clock, produces the
reference at every tick, validates new trajectories, splices them onto the current reference
(no jump), monitors tracking against tolerances, and runs the feedback watchdog. The node only
feeds it messages and the clock and publishes what it returns. Its parts live in one file each:
:mod:`.validation`, :mod:`.splicing`, :mod:`.monitoring`, :mod:`.limiting`; its values and
events in :mod:`.events`.

Times are seconds on one clock (the node's ROS clock).
"""

from __future__ import annotations

import numpy as np

from picking_core.trajectory import PiecewisePolynomial

from .events import LEADS, MIN_LEAD, Event, LateTrajectory, Mode, Prepared, Tolerances  # noqa: F401  (the API)
from .goals import ErrorCode, JointTolerances, Outcome  # noqa: F401  (the API)
from .limiting import CommandLimits
from .monitoring import Monitoring
from .splicing import Splicing
from .validation import Validation


class ControllerCore(Monitoring, Splicing, CommandLimits, Validation):
    """Reference generation and supervision for one arm.

    Parameters
    ----------
    names : sequence of str
        The arm's joints, in command order.
    lower, upper, max_velocity, max_acceleration : array_like
        Limits per joint (inf where none).
    tolerances : Tolerances
    optional : sequence of str
        Joints a trajectory may leave out (a gripper): they hold their reference.
    stall_limit : float
        s: ticks farther apart than this (a stalled loop) delay the trajectory by
        the excess instead of making the reference jump ahead (see :meth:`advance`).
    """

    def __init__(self, names, lower, upper, max_velocity, max_acceleration, tolerances=Tolerances(),
                 optional=(), stall_limit=0.05):
        if not stall_limit > 0:
            raise ValueError(f'stall_limit must be > 0 s, got {stall_limit}')
        self.names = list(names)
        self.optional = set(optional)
        self.n = len(self.names)
        self.lower = np.asarray(lower, float)
        self.upper = np.asarray(upper, float)
        self.max_velocity = np.asarray(max_velocity, float)
        self.max_acceleration = np.asarray(max_acceleration, float)
        self.tol = tolerances
        self.default_tolerances = JointTolerances.default(tolerances, self.n)
        self.active_tolerances = self.default_tolerances   # the running trajectory's
        self.goal = None                 # the action goal the running trajectory is for, if any
        self.canceling = False           # that goal was canceled: the reference brakes to rest
        self._pending = []               # events raised while switching trajectories, sent with the command
        self.mode = Mode.WAITING         # waiting -> holding <-> moving; fault on a violation
        self.traj: PiecewisePolynomial | None = None
        self.t0 = 0.0                    # clock time of the trajectory's t = 0
        self.origin = 0.0                # clock time of its message's time_from_start 0, stalls added
        self.lead_in_end = -np.inf       # clock time its lead-in to its first point ends
        self.measured_q = None
        self.measured_qd = None
        self.measured_time = None
        self.feedback_ok = False
        self.max_error = np.zeros(self.n)
        self.version = 0                 # counts changes of the active trajectory
        self.next = None                 # a Prepared trajectory waiting for its splice time
        self._last_command = None        # (q, time) of the last command sent
        self.limited = 0                 # ticks whose command had to be limited
        self._limited_version = -1
        self.stall_limit = float(stall_limit)
        self.delayed = 0.0               # s the trajectories were delayed by stalled ticks, in all
        self._last_tick = None
        self._stalled_until = -np.inf    # when the last stall ended (its delay was applied)
        self._stall_reported = -np.inf

    def set_tolerances(self, tolerances, stall_limit):
        """New default tolerances and stall limit: for the trajectories that start from now on (a running
        one keeps its own; the feedback watchdog's ``state_timeout`` applies at once)."""
        if not stall_limit > 0:
            raise ValueError(f'stall_limit must be > 0 s, got {stall_limit}')
        self.tol = tolerances
        self.default_tolerances = JointTolerances.default(tolerances, self.n)
        self.stall_limit = float(stall_limit)
