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

from .limits import feasible_start
from .planner import Planner
from .settings import (
                       DEFAULT_JERK_PER_ACCEL,
                       JERK_UNBOUNDED,
                       JOINT_METHODS,
                       PATH_METHODS,
                       PLAN_MARGIN,
                       POSE_METHODS,
                       STRETCH_TIGHT,
                       VIA_SPEEDS,
                       Plan,
                       PlannerSettings,
                       Segment,
)

__all__ = ['DEFAULT_JERK_PER_ACCEL', 'JERK_UNBOUNDED', 'JOINT_METHODS', 'PATH_METHODS', 'PLAN_MARGIN', 'POSE_METHODS',
           'STRETCH_TIGHT', 'VIA_SPEEDS', 'Plan', 'Planner', 'PlannerSettings', 'Segment', 'feasible_start']
