"""A trajectory as the timed points of a ``trajectory_msgs/JointTrajectory`` that a controller
joining them with quintics runs exactly, acceleration steps included.

A controller builds, between two points, the quintic that meets both points' position, velocity
and acceleration (ros2_controllers does; so does ours). Through points sampled every 10 ms of a
plan whose acceleration steps between two of them (the blends of an LSPB, the joins of cubics)
that quintic overshoots the plan's acceleration by up to 38 % of the step: the controller then
runs something other than the plan that was checked. :func:`waypoints` places a point at every
break of the plan, so that each pair of neighbouring points lies within one of the plan's
polynomials (degree <= 5) and the quintic between them *is* that polynomial; and where the
acceleration steps, two points :data:`STEP` apart: the first with the state at the step and the
acceleration before it, the second with the state :data:`STEP` after it. A controller that joins
every pair of points with a quintic runs the plan exactly but for that microsecond;
:func:`through_waypoints`, the controller's reading, runs the segment after the step from the step
itself, so exactly throughout.
"""

from __future__ import annotations

import numpy as np

from .piecewise import PiecewisePolynomial, taylor_shift
from .polynomial import hermite_coeffs

#: Time between the two points of an acceleration step, s.
STEP = 1e-6
# Breaks closer than this merge (a piece of the plan this short moves nothing a controller sees).
_MERGE = 1e-5


def one_sided(traj, t, after, at=None):
    """``(q, qd, qdd)`` of the PiecewisePolynomial ``traj`` at times ``t`` (on its own clock, within
    it), each (N, n): at a break, the limit from the segment ``after`` it (True) or before it. With
    ``at``, the segments are those of the times ``at`` and evaluated at ``t`` (a hair beside them).
    Beyond its ends the state is the end's, held (as a controller holds a trajectory's last point; the
    last polynomial, extrapolated, left the joints' range within a second)."""
    b = traj.breaks
    t = np.clip(np.asarray(t, float), b[0], b[-1])
    k = np.clip(np.searchsorted(b, t if at is None else at, side='right' if after else 'left') - 1, 0, len(b) - 2)
    tau = (t - b[k])[:, None]
    c = traj.coeffs[k]                                                   # (N, 6, n)
    q = c[:, 0] + tau * (c[:, 1] + tau * (c[:, 2] + tau * (c[:, 3] + tau * (c[:, 4] + tau * c[:, 5]))))
    qd = c[:, 1] + tau * (2 * c[:, 2] + tau * (3 * c[:, 3] + tau * (4 * c[:, 4] + tau * 5 * c[:, 5])))
    qdd = 2 * c[:, 2] + tau * (6 * c[:, 3] + tau * (12 * c[:, 4] + tau * 20 * c[:, 5]))
    return q, qd, qdd


def waypoints(traj, period, t_from=None, t_until=None, before=None, end=True):
    """Points ``(t, q, qd, qdd)`` of ``traj`` from ``t_from`` to ``t_until`` (its clock; default its
    start and end), ``t`` counted from ``t_from`` in whole nanoseconds (a message's resolution: the
    states are those of the times sent).

    Every ``period`` s, at every break of ``traj`` between, and where the acceleration steps two
    points :data:`STEP` apart (see the module). ``before``: the acceleration just before ``t_from``
    (the reference the plan starts from), a step there too when it differs. ``end=False`` leaves
    out ``t_until`` and what lies within ``period / 2`` before it (the next plan's points go on
    from there).
    """
    lo = traj.start_time if t_from is None else float(t_from)
    hi = traj.end_time if t_until is None else float(t_until)
    grid = lo + np.arange(int(np.floor((hi - lo) / period + 1e-9)) + 1) * period
    b = traj.breaks
    inner = b[(b > lo + _MERGE) & (b < hi - _MERGE)]
    inner = inner[np.concatenate(([True], np.diff(inner) > _MERGE))] if inner.size else inner
    # Samples right beside a break or the end add nothing but a sliver of a segment.
    keep = grid < hi - period * (0.25 if end else 0.5)
    if inner.size:
        keep &= np.abs(grid[:, None] - inner[None, :]).min(axis=1) >= period / 4
    keep[0] = True
    t = np.union1d(grid[keep], inner)
    if end and hi > lo:
        t = np.append(t[t < hi - _MERGE], hi)
    # The times as sent, and each one's segments before and after it (at a break, two).
    sent = np.round((t - lo) * 1e9) * 1e-9
    q, qd, qdd = one_sided(traj, lo + sent, after=True, at=t)
    left = one_sided(traj, lo + sent, after=False, at=t)[2]
    left[0] = qdd[0]
    if before is not None:
        before = np.asarray(before, float).ravel()[:traj.n_joints]
        left[0, :before.size] = before
    if end:
        q[-1], qd[-1], qdd[-1] = (x[-1] for x in one_sided(traj, lo + sent[-1:], after=False, at=t[-1:]))
        left[-1] = qdd[-1]
    steps = np.flatnonzero(np.abs(left - qdd).max(axis=1) > 1e-9 * (1.0 + np.abs(qdd).max()))
    # Each step: a point with the acceleration before it, then the state STEP after it.
    at = np.sort(np.concatenate((np.arange(t.size), steps)))
    second = np.concatenate(([False], at[1:] == at[:-1]))
    first = np.concatenate((second[1:], [False]))
    times = sent[at] + np.where(second, STEP, 0.0)
    q, qd, qdd = q[at], qd[at], qdd[at]
    qdd[first] = left[at[first]]
    q[second], qd[second], qdd[second] = one_sided(traj, lo + times[second], after=True, at=t[at[second]])
    return times, q, qd, qdd


def step_pairs(times):
    """For points at ``times`` (s, increasing) as :func:`waypoints` makes them: a boolean mask of the
    points that are the second of an acceleration step (less than two :data:`STEP` after the one
    before)."""
    t = np.asarray(times, float)
    return np.concatenate(([False], np.diff(t) < 2 * STEP))


def through_waypoints(t, q, qd, qdd):
    """The trajectory through timed points ``(t, q, qd, qdd)`` (each (m, n) but ``t``, at least two
    points): between neighbours the quintic that meets both; two points less than two :data:`STEP`
    apart are an acceleration step at the first, where the segment after the second begins (see the
    module). Returns a :class:`PiecewisePolynomial` from ``t[0]``; the inverse of :func:`waypoints`."""
    t = np.asarray(t, float)
    q, qd, qdd = (np.asarray(x, float) for x in (q, qd, qdd))
    second = step_pairs(t)
    if (~second).sum() < 2:
        raise ValueError('the points span no time (a single instant)')
    c = hermite_coeffs(q[:-1], qd[:-1], qdd[:-1], q[1:], qd[1:], qdd[1:], np.diff(t)[:, None]).transpose(0, 2, 1)
    # Drop each step's microsecond: the segment after it, extended back to the step's first point.
    keep = ~second[1:]                                  # segments that do not end at a step's second point
    after = np.flatnonzero(second[:-1])                 # segments that start at a step's second point
    c[after] = taylor_shift(c[after], t[after - 1] - t[after])
    return PiecewisePolynomial(t[~second], c[keep])
