"""Measuring a run: tracking error, tool deviation from lines and arcs, peaks, jerk (pure core)."""

from __future__ import annotations

import numpy as np

from . import geometry

#: How far the controller's commanded reference may be from the plan it runs, in position (rad),
#: velocity (rad/s) and acceleration (rad/s^2), measured from the stamps of its joint_commands.
#: The controller's core runs a plan within 1e-9 rad, 1e-7 rad/s and 1e-4 rad/s^2; on ROS time,
#: seconds of the epoch as floats resolve a quarter of a microsecond, which at the joints' speeds
#: and accelerations is the bound's size.
REFERENCE_BOUND = (1e-5, 1e-4, 1e-2)


def tracking_error(t_plan, q_plan, t_meas, q_meas):
    """Measured minus planned positions at the measurement times, (N, n); NaN outside the plan."""
    err = np.full(q_meas.shape, np.nan)
    inside = (t_meas >= t_plan[0]) & (t_meas <= t_plan[-1])
    for j in range(q_meas.shape[1]):
        err[inside, j] = q_meas[inside, j] - np.interp(t_meas[inside], t_plan, q_plan[:, j])
    return err


def distance_to_segment(p, a, b):
    """Distance of points ``p`` (N, 3) from the segment ``a``-``b``, m."""
    ab = b - a
    denom = float(ab @ ab)
    w = np.zeros(len(p)) if denom == 0 else np.clip((p - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(p - (a + w[:, None] * ab), axis=1)


def distance_to_arc_circle(p, arc):
    """Distance of points ``p`` (N, 3) from the circle that carries ``arc``, m."""
    d = p - arc.center
    off_plane = d @ arc.normal
    in_plane = np.linalg.norm(d - off_plane[:, None] * arc.normal, axis=1)
    return np.hypot(in_plane - arc.radius, off_plane)


def cartesian_deviation(kind, tool_start, tool_mid, tool_end, tool_measured):
    """Largest distance of measured tool points from the requested line or arc, m."""
    if kind == 'arc':
        try:
            arc = geometry.Arc.through(tool_start, tool_mid, tool_end)
        except ValueError:
            return float(distance_to_segment(tool_measured, tool_start, tool_end).max())
        return float(distance_to_arc_circle(tool_measured, arc).max())
    return float(distance_to_segment(tool_measured, tool_start, tool_end).max())


def peak_jerk(t, qdd):
    """Largest |d qdd / dt| per joint from sampled accelerations (finite differences; sample them
    evenly: a plan's points put two a microsecond apart where the acceleration steps)."""
    dt = np.diff(t)
    keep = dt > 1e-9
    return np.max(np.abs(np.diff(qdd, axis=0)[keep] / dt[keep, None]), axis=0)


def parse_segments(text):
    """``'label: method 1.234 s; ...'`` (planner_status) -> [(label, method, duration)]."""
    out = []
    for part in filter(None, (p.strip() for p in text.split(';'))):
        label, rest = part.rsplit(':', 1)
        method, duration, _ = rest.split()
        out.append((label.strip(), method, float(duration)))
    return out


#: The blended pick cycle's corners: (name, the line that ends or starts there, 1 if it ends there (0: starts),
#: the joint move on the other side).
PICK_CORNERS = (('P1', 'P2 to the apple', 0, 'P1 approach'),
                ('P3', 'P3 lift and detach', 1, 'P4 above the box'),
                ('P4 in', 'P5 into the box', 0, 'P4 above the box'),
                ('P4 out', 'P4 out of the box', 1, 'P0 back home'))


def _segment(plan, label):
    return next(s for s in plan.segments if s.label == label)


def pick_corners(arm, plan):
    """The corners of a blended pick cycle planned without a blend radius (``PickSettings.blend``):
    ``(name, point, direction)`` per corner of :data:`PICK_CORNERS`, the point where its line ends
    or starts (m) and the line's unit direction toward it."""
    out = []
    for name, line, end, _ in PICK_CORNERS:
        seg = _segment(plan, line)
        q = plan.trajectory.sample([seg.start, seg.start + seg.duration])[0][:, :arm.dof]
        ends = arm.fk(q)[:, :3, 3]
        toward = ends[1] - ends[0] if end else ends[0] - ends[1]
        out.append((name, ends[end], toward / np.linalg.norm(toward)))
    return out


def corner_path(arm, plan, name, samples=2000):
    """The tool's positions (N, 3) in ``plan`` along the line and the joint move that meet at the
    corner ``name`` of :data:`PICK_CORNERS`, in time order."""
    _, line, end, move = next(c for c in PICK_CORNERS if c[0] == name)
    first, second = (_segment(plan, line), _segment(plan, move))[::1 if end else -1]
    t = np.linspace(first.start, second.start + second.duration, samples)
    return arm.fk(plan.trajectory.sample(t)[0][:, :arm.dof])[:, :3, 3]


def reference_deviation(plan, t0, t_cmd, q_cmd, qd_cmd, qdd_cmd):
    """Largest |commanded - planned| of position, velocity and acceleration over the commands
    stamped ``t_cmd`` within the plan (a PiecewisePolynomial starting at clock time ``t0``), each
    per joint, and how many commands that was; the commands' columns are the plan's joints."""
    inside = (t_cmd >= t0) & (t_cmd <= t0 + plan.duration)
    if not inside.any():
        return None
    want = plan.sample(t_cmd[inside] - t0)
    return (*(np.abs(got[inside] - w).max(axis=0) for got, w in zip((q_cmd, qd_cmd, qdd_cmd), want)),
            int(inside.sum()))
