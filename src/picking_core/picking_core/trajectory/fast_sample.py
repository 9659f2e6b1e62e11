"""Trajectory kernels compiled: long samplings of a synchronised move, short ones of many
segments, and the spline through a path's samples.

:func:`sample_shared`: one pass that writes q, qd and qdd of a synchronised move.

Where every joint of a segment follows one profile, ``q_j(tau) = c0_j + w_j s(tau)``
(see :func:`.piecewise._shared_profile`), a sampling of thousands of times costs
little more than writing its output (3 x n_joints doubles a sample): ``s``, ``s'``
and ``s''`` are evaluated by Horner's scheme (up to :data:`CHUNK` times at once), then
scaled into each output row in turn, every loop over contiguous memory so that LLVM
vectorises it and the output is written front to back. numpy needs a dozen passes
over the samples for the same (the power basis, a small matrix product, the scaling
and the start positions), and the small product alone cost more than the output's
write.

:func:`sample_pieces`: a trajectory of many segments (a spline through a line's IK
samples, a whole pick cycle) or of one at up to a few thousand times, each sample's segment
found by bisection and its q, qd and qdd evaluated by Horner's scheme from the
position coefficients (no derivative table to build first: most trajectories a
planner makes are sampled once), where numpy needs a dozen calls (search, clip,
gather, power basis, a batched product of tiny matrices), each with its own overhead.

:func:`quintic_spline`: the C2 spline through a line's 50-odd IK samples (a
tridiagonal solve and a quintic per segment), where numpy's LAPACK call and dozen
array expressions cost more than their arithmetic.

:func:`scan_limits` (the joint-limit check of every planned move),
:func:`merge_pieces` (each joint's LSPB phases merged over the union of their breaks),
:func:`phase_pieces` and :func:`add_smoothstep` (a Ruckig move as one piecewise cubic,
ending exactly on its target) and :func:`via_timing` (the blends of LSPB through via
points, which the planner searches durations with) do in one pass what numpy does in a
dozen or fifty small calls: a pick cycle times about eighty Ruckig moves.

Imported by :mod:`.piecewise` when a segment is sampled at thousands of times, and
for the rest only in a process that asked for them (a planner: see
:func:`.piecewise.use_compiled_kernels`), so that a controller never stalls on
numba's import. numba compiles them when this module is first imported and keeps
the machine code in its cache beside this file, as for the kinematics' kernels;
``make`` builds that cache when it installs.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

_IN = types.Array(types.float64, 1, 'C', readonly=True)
_PROFILE = types.Array(types.float64, 2, 'C', readonly=True)
_OUT = types.Array(types.float64, 2, 'C')
# One signature, compiled (or loaded from the cache) at import: a call with other types raises
# TypeError instead of compiling a new version in the middle of sampling. Contiguous arrays
# only: with unknown strides ('A') or an index computed in the inner loop, LLVM does not
# vectorise the loops.
SIGNATURE = types.boolean(_IN, types.float64, types.float64, types.float64, _PROFILE, _IN, _IN, _OUT, types.intp)

#: Samples per chunk (the chunk's profile, 3 x 131 072 doubles, 3 MiB, stays in the L2 or L3
#: cache). Each output row is written whole for a chunk, so that a sampling of up to this many
#: times writes its output front to back, as a fill does, instead of taking turns among the
#: rows in small pieces, which costs far more once the output has left the caches.
CHUNK = 1 << 17


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def sample_shared(t, lo, hi, origin, profile, w, c0, out, col):
    """Write q, qd, qdd at times ``t`` into ``out[:, col:col + len(t)]`` (out: 3n rows, q then
    qd then qdd); return True if a time lies outside ``[lo, hi]`` or is NaN: the check of the
    times, in the pass that reads them (a caller then looks at them again; two passes of numpy
    over 100 000 times cost more than the count here).

    ``profile`` (3, 6): power-basis coefficients of ``s``, ``s'`` and ``s''`` in local time
    ``tau = t - origin``, the time first clipped to ``[lo, hi]``; ``w`` (n,) the joints'
    scales; ``c0`` (n,) their positions at ``tau = 0``.
    """
    n = w.size
    size = t.size
    s = np.empty((3, min(CHUNK, size)))
    odd = 0
    for a in range(0, size, CHUNK):
        m = min(CHUNK, size - a)
        times = t[a:a + m]
        for r in range(3):
            c5, c4, c3, c2, c1, c = profile[r, 5], profile[r, 4], profile[r, 3], profile[r, 2], profile[r, 1], \
                profile[r, 0]
            sr = s[r]
            if r == 0:
                for k in range(m):
                    x = times[k]
                    odd += 0 if (x >= lo) & (x <= hi) else 1      # NaN too
                    x = min(max(x, lo), hi) - origin
                    sr[k] = ((((c5 * x + c4) * x + c3) * x + c2) * x + c1) * x + c
            else:
                for k in range(m):
                    x = min(max(times[k], lo), hi) - origin
                    sr[k] = ((((c5 * x + c4) * x + c3) * x + c2) * x + c1) * x + c
        for r in range(3):
            src = s[r]
            for j in range(n):
                wj = w[j]
                cj = c0[j] if r == 0 else 0.0
                dst = out[r * n + j][col + a:col + a + m]
                for k in range(m):
                    dst[k] = cj + wj * src[k]
    return odd > 0


_SEGMENTS = types.Array(types.float64, 3, 'C', readonly=True)
PIECES = types.void(_IN, _SEGMENTS, _IN, _OUT)


@njit(PIECES, cache=True, nogil=True, error_model='numpy')
def sample_pieces(breaks, coeffs, t, out):
    """Write q, qd, qdd at times ``t`` (any order) into ``out`` (3n rows, q then qd then qdd,
    one column per time).

    ``coeffs`` (m, 6, n): each segment's power-basis coefficients of q in its local time
    (those of qd and qdd follow, by Horner's scheme too). Segment ``k`` covers
    ``(breaks[k], breaks[k + 1]]`` (the first one its start too); a time before the start
    holds the first point, after the end the last, at rest.
    """
    m = breaks.size - 1
    n = coeffs.shape[2]
    b0, b1 = breaks[0], breaks[m]
    for i in range(t.size):
        x = t[i]
        held = x < b0 or x > b1
        x = min(max(x, b0), b1)
        lo, hi = 0, m - 1                 # the first k with x <= breaks[k + 1]
        while lo < hi:
            mid = (lo + hi) // 2
            if x <= breaks[mid + 1]:
                hi = mid
            else:
                lo = mid + 1
        tau = x - breaks[lo]
        c = coeffs[lo]
        for j in range(n):
            c0, c1, c2, c3, c4, c5 = c[0, j], c[1, j], c[2, j], c[3, j], c[4, j], c[5, j]
            out[j, i] = ((((c5 * tau + c4) * tau + c3) * tau + c2) * tau + c1) * tau + c0
            if held:
                out[n + j, i] = out[2 * n + j, i] = 0.0
            else:
                out[n + j, i] = (((5.0 * c5 * tau + 4.0 * c4) * tau + 3.0 * c3) * tau + 2.0 * c2) * tau + c1
                out[2 * n + j, i] = ((20.0 * c5 * tau + 12.0 * c4) * tau + 6.0 * c3) * tau + 2.0 * c2


_POINTS = types.Array(types.float64, 2, 'C', readonly=True)
_COEFFS = types.Array(types.float64, 3, 'C')
SPLINE = types.void(_IN, _POINTS, types.boolean, types.boolean, _COEFFS)


@njit(SPLINE, cache=True, nogil=True, error_model='numpy')
def quintic_spline(h, points, free_start, free_end, out):
    """The quintic segments of :func:`.via.quintic_via` without given velocities, into ``out``
    (m, 6, n): through ``points`` (m + 1, n) at intervals ``h`` (m,) > 0, each knot's velocity
    and acceleration those of the C2 cubic spline through the points (see
    :func:`.via._cubic_spline`, whose equations these are), an end at rest or ``free``
    (not-a-knot; m >= 2, and m >= 3 if both are).

    The tridiagonal system is solved by elimination without pivoting (Thomas): every row is
    diagonally dominant but a free end's, and eliminating that one with its neighbour leaves
    the pivot h_0 + h_1 > 0.
    """
    m, n = h.size, points.shape[1]
    diag, upper, lower = np.ones(m + 1), np.zeros(m), np.zeros(m)
    for i in range(1, m):
        diag[i] = 2.0 * (h[i - 1] + h[i])
        upper[i] = h[i - 1]
        lower[i - 1] = h[i]
    if free_start:
        diag[0], upper[0] = h[1], h[0] + h[1]
    if free_end:
        diag[m], lower[m - 1] = h[m - 2], h[m - 1] + h[m - 2]
    vel = np.zeros((m + 1, n))
    acc = np.zeros((m + 1, n))
    slope = np.empty((m, n))
    for i in range(m):
        for j in range(n):
            slope[i, j] = (points[i + 1, j] - points[i, j]) / h[i]
    for i in range(1, m):                                    # the right-hand side, in vel
        for j in range(n):
            vel[i, j] = 3.0 * (h[i] * slope[i - 1, j] + h[i - 1] * slope[i, j])
    if free_start:
        for j in range(n):
            vel[0, j] = ((3.0 * h[0] + 2.0 * h[1]) * h[1] * slope[0, j] + h[0] ** 2 * slope[1, j]) / (h[0] + h[1])
    if free_end:
        span = h[m - 1] + h[m - 2]
        for j in range(n):
            vel[m, j] = ((3.0 * h[m - 1] + 2.0 * h[m - 2]) * h[m - 2] * slope[m - 1, j]
                         + h[m - 1] ** 2 * slope[m - 2, j]) / span
    # Forward elimination, then back substitution, all joints at once.
    ratio = np.empty(m)
    ratio[0] = upper[0] / diag[0]
    for j in range(n):
        vel[0, j] /= diag[0]
    for i in range(1, m + 1):
        pivot = diag[i] - lower[i - 1] * ratio[i - 1]
        if i < m:
            ratio[i] = upper[i] / pivot
        for j in range(n):
            vel[i, j] = (vel[i, j] - lower[i - 1] * vel[i - 1, j]) / pivot
    for i in range(m - 1, -1, -1):
        for j in range(n):
            vel[i, j] -= ratio[i] * vel[i + 1, j]
    for i in range(m):
        for j in range(n):
            acc[i, j] = 2.0 * (3.0 * slope[i, j] - 2.0 * vel[i, j] - vel[i + 1, j]) / h[i]
    if free_end:
        for j in range(n):
            acc[m, j] = 2.0 * (vel[m - 1, j] + 2.0 * vel[m, j] - 3.0 * slope[m - 1, j]) / h[m - 1]
    if not free_start:
        for j in range(n):
            acc[0, j] = 0.0
    # Each segment's quintic from its end states (polynomial.hermite_coeffs).
    for i in range(m):
        T = h[i]
        T2 = T * T
        for j in range(n):
            q0, v0, a0 = points[i, j], vel[i, j], acc[i, j]
            d, v1, a1 = points[i + 1, j] - q0, vel[i + 1, j], acc[i + 1, j]
            out[i, 0, j] = q0
            out[i, 1, j] = v0
            out[i, 2, j] = 0.5 * a0
            out[i, 3, j] = (20.0 * d - (8.0 * v1 + 12.0 * v0) * T - (3.0 * a0 - a1) * T2) / (2.0 * T2 * T)
            out[i, 4, j] = (-30.0 * d + (14.0 * v1 + 16.0 * v0) * T + (3.0 * a0 - 2.0 * a1) * T2) / (2.0 * T2 * T2)
            out[i, 5, j] = (12.0 * d - 6.0 * (v1 + v0) * T + (a1 - a0) * T2) / (2.0 * T2 * T2 * T)


_VALUES = types.Array(types.float64, 2, 'A', readonly=True)
SCAN = types.Tuple((types.intp, types.boolean))(_VALUES, _IN, _IN)


@njit(SCAN, cache=True, nogil=True, error_model='numpy')
def scan_limits(values, lo, hi):
    """``(first, nonfinite)`` for samples ``values`` (N, n) against per-joint bounds ``lo``,
    ``hi`` (n,): the flat index ``i * n + j`` of the first finite value outside its bounds
    (-1 if none), and whether any value is not finite (one pass, for
    :func:`..kinematics.paths.check_joint_limits`)."""
    first = -1
    nonfinite = False
    n = values.shape[1]
    for i in range(values.shape[0]):
        for j in range(n):
            v = values[i, j]
            if not math.isfinite(v):
                nonfinite = True
            elif first < 0 and (v < lo[j] or v > hi[j]):
                first = i * n + j
    return first, nonfinite


_BREAKS = types.Array(types.float64, 2, 'C', readonly=True)
_PIECES = types.Array(types.float64, 3, 'C', readonly=True)
MERGE = types.void(_BREAKS, _PIECES, _IN, _COEFFS)


@njit(MERGE, cache=True, nogil=True, error_model='numpy')
def merge_pieces(joint_breaks, joint_coeffs, union, out):
    """Each joint's polynomial on each interval of ``union`` into ``out`` (K, 6, n), for
    :func:`.piecewise.merge_joint_pieces`: the joint's piece (P of them, bounds
    ``joint_breaks`` (P + 1, n), coefficients ``joint_coeffs`` (P, 6, n)) that holds the
    interval's midpoint, re-expanded about the interval's start by synthetic division, in
    the order of :func:`.piecewise.taylor_shift` (zero leading coefficients skipped)."""
    n_pieces, _, n = joint_coeffs.shape
    c = np.empty(6)
    for k in range(union.size - 1):
        start = union[k]
        mid = 0.5 * (union[k] + union[k + 1])
        for j in range(n):
            p = 0
            for r in range(1, n_pieces):
                if mid >= joint_breaks[r, j]:
                    p += 1
            dt = start - joint_breaks[p, j]
            degree = 0
            for i in range(6):
                c[i] = joint_coeffs[p, i, j]
                if c[i] != 0.0:
                    degree = i
            for i in range(degree):
                for m in range(degree - 1, i - 1, -1):
                    c[m] += c[m + 1] * dt
            for i in range(6):
                out[k, i, j] = c[i]


_RTOL = 1e-9          # as .lspb._RTOL: "exactly the minimum" up to rounding
VIA = types.Tuple((types.intp, types.intp, types.intp, types.float64))(_POINTS, _IN, _IN, _OUT, _OUT)


@njit(VIA, cache=True, nogil=True, error_model='numpy')
def via_timing(points, td, a, tb, vel):
    """Craig's blend times ``tb`` (m + 1, n) and line velocities ``vel`` (m, n) through via
    ``points`` (m + 1, n), m >= 2, for :func:`.lspb._via_timing`, in the numpy version's
    operations and order (the same bits).

    Returns ``(failed, k, j, need)``: 0 when the timing exists; 1 when the first (k = 0) or
    last (k = 1) segment of joint j is too short to reach its line from rest; 2 when the
    blends of segment k of joint j need ``need`` s, more than it lasts. The numpy version's
    choice of k and j: the most short of the first end that is short, else of all segments.
    """
    m = points.shape[0] - 1
    n = points.shape[1]
    for k in range(m):
        for j in range(n):
            vel[k, j] = (points[k + 1, j] - points[k, j]) / td[k]
    for end in range(2):
        k = 0 if end == 0 else m - 1
        span = td[k]
        worst, at = 0.0, -1
        for j in range(n):
            disc = span * span - 2.0 * abs(points[k + 1, j] - points[k, j]) / a[j]
            if at < 0 or disc < worst:
                worst, at = disc, j
            tb[0 if end == 0 else m, j] = disc       # the blend, once no end is short
        if worst < -_RTOL * (span * span):
            return 1, end, at, 0.0
    for end in range(2):
        k = 0 if end == 0 else m - 1
        span = td[k]
        row = 0 if end == 0 else m
        for j in range(n):                          # the ends blend from (to) rest
            blend = span - math.sqrt(max(tb[row, j], 0.0))
            tb[row, j] = blend
            vel[k, j] = (points[k + 1, j] - points[k, j]) / (span - 0.5 * blend)
    for k in range(1, m):
        for j in range(n):
            tb[k, j] = abs(vel[k, j] - vel[k - 1, j]) / a[j]
    short, worst, wk, wj = False, 0.0, -1, -1
    for k in range(m):
        for j in range(n):
            linear = td[k] - 0.5 * tb[k, j] - 0.5 * tb[k + 1, j]
            if k == 0:
                linear -= 0.5 * tb[0, j]
            if k == m - 1:
                linear -= 0.5 * tb[m, j]
            short = short or linear < -_RTOL * td[k]
            if wk < 0 or linear < worst:
                worst, wk, wj = linear, k, j
    if short:
        return 2, wk, wj, td[wk] - worst
    return 0, 0, 0, 0.0


_PHASES = types.Array(types.float64, 3, 'C', readonly=True)
_BREAKS_OUT = types.Array(types.float64, 1, 'C')
PHASES = types.intp(_PHASES, _IN, types.float64, _BREAKS_OUT, _COEFFS)


@njit(PHASES, cache=True, nogil=True, error_model='numpy')
def phase_pieces(phases, end, duration, breaks, coeffs):
    """Ruckig's per-joint phases as one piecewise cubic, for :func:`.optimal._pieces` (the same
    arithmetic): ``phases`` (5, n, 9) holds each joint's nine phases (brake pre-phase, seven jerk
    phases) as durations, start positions, velocities, accelerations and jerks; ``end`` (n,)
    where each stops, held until ``duration``. Writes the union of the joints' boundaries into
    ``breaks`` and each joint's cubic on each interval into ``coeffs`` (zeroed, K >= intervals);
    returns the number of intervals K."""
    n = phases.shape[1]
    starts = np.empty((n, 11))
    for j in range(n):
        t = 0.0
        starts[j, 0] = 0.0
        for k in range(9):
            t += phases[0, j, k]
            starts[j, k + 1] = t
        starts[j, 10] = max(t, duration)
    flat = np.sort(starts.ravel())
    last = flat[-1]
    tol = 1e-12 * max(last - flat[0], 1.0)
    m = 1
    breaks[0] = flat[0]
    for i in range(1, flat.size):
        if flat[i] - flat[i - 1] > tol:
            breaks[m] = flat[i]
            m += 1
    breaks[m - 1] = last
    for k in range(m - 1):
        start = breaks[k]
        mid = 0.5 * (breaks[k] + breaks[k + 1])
        for j in range(n):
            piece = 0
            for r in range(1, 10):
                if mid >= starts[j, r]:
                    piece = r
            dt = start - starts[j, piece]
            if piece == 9:
                coeffs[k, 0, j] = end[j]
                continue
            p, v, a, jerk = phases[1, j, piece], phases[2, j, piece], phases[3, j, piece], phases[4, j, piece]
            coeffs[k, 0, j] = p + dt * (v + dt * (0.5 * a + dt * jerk / 6.0))
            coeffs[k, 1, j] = v + dt * (a + 0.5 * dt * jerk)
            coeffs[k, 2, j] = 0.5 * (a + dt * jerk)
            coeffs[k, 3, j] = jerk / 6.0
    return m - 1


SMOOTHSTEP = types.void(_IN, _COEFFS, _IN)


@njit(SMOOTHSTEP, cache=True, nogil=True, error_model='numpy')
def add_smoothstep(breaks, coeffs, error):
    """``error * (10 x^3 - 15 x^4 + 6 x^5)``, x the time over the whole of ``breaks``, added to
    each piece of ``coeffs`` (K, 6, n) about its own start, for :func:`.optimal._ending_at`."""
    T = breaks[-1] - breaks[0]
    T2 = T * T
    T3, T4, T5 = T2 * T, T2 * T2, T2 * T2 * T
    for k in range(coeffs.shape[0]):
        x = (breaks[k] - breaks[0]) / T
        x2 = x * x
        for j in range(coeffs.shape[2]):
            e = error[j]
            coeffs[k, 0, j] += e * (x2 * x) * (10.0 - 15.0 * x + 6.0 * x2)
            coeffs[k, 1, j] += e / T * x2 * (30.0 - 60.0 * x + 30.0 * x2)
            coeffs[k, 2, j] += e / T2 * x * (30.0 - 90.0 * x + 60.0 * x2)
            coeffs[k, 3, j] += e / T3 * (10.0 - 60.0 * x + 60.0 * x2)
            coeffs[k, 4, j] += e / T4 * (-15.0 + 30.0 * x)
            coeffs[k, 5, j] += e / T5 * 6.0
