"""The offset-wrist (Universal Robots) closed-form IK, compiled: the fast path of
:class:`.solvers.OffsetWrist6R`.

The same solutions as the vectorised :meth:`.solvers.OffsetWrist6R.candidates`
(two waist, two wrist 2 and two elbow angles; each joint moved to its 2 pi image
nearest the seed within the limits; the valid solution nearest the seed), with
the status codes and input checks of :mod:`.fast_ik`. The model is packed in
arrays (see :func:`pack`):

- ``dh``: d4, d5, d6, a2, a3 (m) of the Denavit-Hartenberg form;
- ``offsets``: each joint's Denavit-Hartenberg angle at the URDF's zero (rad);
- ``base_inv``, ``tool_inv``: the inverse fixed transforms before joint 1 and after joint 6;
- ``limits``: rows lower, upper, revolute flag, one column per joint.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fast_ik import BEYOND_LIMITS, OK, OUT_OF_REACH, Bound, check_inputs, image

_SINGULAR = 1e-9      # |sin q5| below which the wrist is singular (the vectorised path's)


def pack(solver):
    """The solver's model as the arrays the kernel takes."""
    dh = np.array([solver.d4, solver.d5, solver.d6, solver.a2, solver.a3], dtype=float)
    limits = np.array([solver.arm.lower, solver.arm.upper, solver.revolute], dtype=float)
    return (dh, np.ascontiguousarray(solver.offsets, dtype=float), np.ascontiguousarray(solver.base_inv),
            np.ascontiguousarray(solver.tool_inv), limits)


def bind(solver):
    """This module's kernels bound to ``solver``'s arm (:class:`.fast_ik.Bound`)."""
    return Bound(pack(solver), solve, solve_many)


SIGNATURE = ('int64(float64[::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], '
             'float64[:, ::1], float64[::1], float64[::1])')


@njit(cache=True, nogil=True, error_model='numpy')
def _solve(dh, offsets, base_inv, tool_inv, limits, pose, seed, q_out, frames, angles):
    """:func:`solve` with its scratch arrays given (``frames`` 6x4, ``angles`` 12): a batch allocates them once."""
    status = check_inputs(pose, seed)
    if status != OK:
        return status
    d4, d5, d6, a2, a3 = dh[0], dh[1], dh[2], dh[3], dh[4]
    # F = base_inv @ pose @ tool_inv: Denavit-Hartenberg frame 6 in frame 0 (rows 0..2).
    G = frames[:3]
    for i in range(3):
        for j in range(4):
            G[i, j] = (base_inv[i, 0] * pose[0, j] + base_inv[i, 1] * pose[1, j]
                       + base_inv[i, 2] * pose[2, j] + base_inv[i, 3] * pose[3, j])
    F = frames[3:]
    for i in range(3):
        for j in range(4):
            F[i, j] = (G[i, 0] * tool_inv[0, j] + G[i, 1] * tool_inv[1, j]
                       + G[i, 2] * tool_inv[2, j] + G[i, 3] * tool_inv[3, j])
    px, py = F[0, 3], F[1, 3]
    p5x, p5y = px - d6 * F[0, 2], py - d6 * F[1, 2]
    rho = math.hypot(p5x, p5y)
    if rho < abs(d4) or rho == 0.0:
        return OUT_OF_REACH
    psi = math.atan2(p5y, p5x)
    delta = math.asin(d4 / rho)

    best, reached = math.inf, False
    theta, cand = angles[:6], angles[6:]
    for k1 in range(2):
        t1 = psi + delta if k1 == 0 else psi + math.pi - delta
        s1, c1 = math.sin(t1), math.cos(t1)
        c5 = (px * s1 - py * c1 - d4) / d6
        if abs(c5) > 1.0 + 1e-12:
            continue
        u = F[0, 0] * s1 - F[1, 0] * c1
        v = F[0, 1] * s1 - F[1, 1] * c1
        s5_size = math.hypot(u, v)
        for k5 in range(2):
            sign = 1.0 if k5 == 0 else -1.0
            t5 = math.atan2(sign * s5_size, c5)
            s5, c5b = math.sin(t5), math.cos(t5)
            if s5_size < _SINGULAR:
                t6 = seed[5] + offsets[5]
            else:
                t6 = math.atan2(-sign * v, sign * u)
            s6, c6 = math.sin(t6), math.cos(t6)
            # Frame 4 in frame 6 is inv(A6) inv(A5) = Tz(-d6) Rz(-t6) Rx(pi/2) Tz(-d5) Rz(-t5): its x axis
            # and origin, then in frame 0 through F.
            x0, x1, x2 = c5b * c6, -c5b * s6, -s5
            o0, o1, o2 = d5 * s6, d5 * c6, -d6
            ex0 = F[0, 0] * x0 + F[0, 1] * x1 + F[0, 2] * x2
            ex1 = F[1, 0] * x0 + F[1, 1] * x1 + F[1, 2] * x2
            ex2 = F[2, 0] * x0 + F[2, 1] * x1 + F[2, 2] * x2
            ox = F[0, 0] * o0 + F[0, 1] * o1 + F[0, 2] * o2 + F[0, 3]
            oy = F[1, 0] * o0 + F[1, 1] * o1 + F[1, 2] * o2 + F[1, 3]
            oz = F[2, 0] * o0 + F[2, 1] * o1 + F[2, 2] * o2 + F[2, 3]
            # In frame 1, inv(A1) = Rx(-pi/2) Rz(-t1): (a, b, c) -> (c1 a + s1 b, c, s1 a - c1 b).
            x = c1 * ox + s1 * oy
            y = oz
            ex = c1 * ex0 + s1 * ex1
            ey = ex2
            D = (x * x + y * y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
            if abs(D) > 1.0 + 1e-12:
                continue
            reached = True
            t3_up = math.acos(max(-1.0, min(1.0, D)))
            phi = math.atan2(ey, ex)
            for k3 in range(2):
                t3 = t3_up if k3 == 0 else -t3_up
                t2 = math.atan2(y, x) - math.atan2(a3 * math.sin(t3), a2 + a3 * math.cos(t3))
                theta[0], theta[1], theta[2] = t1, t2, t3
                theta[3], theta[4], theta[5] = phi - t2 - t3, t5, t6
                dist, ok = 0.0, True
                for j in range(6):
                    cand[j], ok = image(theta[j] - offsets[j], seed[j], limits[0, j], limits[1, j], limits[2, j])
                    if not ok:
                        break
                    dist += (cand[j] - seed[j]) ** 2
                    if dist >= best:
                        ok = False
                        break
                if ok:
                    best = dist
                    for j in range(6):
                        q_out[j] = cand[j]
    if best < math.inf:
        return OK
    return BEYOND_LIMITS if reached else OUT_OF_REACH


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def solve(dh, offsets, base_inv, tool_inv, limits, pose, seed, q_out):
    """The valid solution nearest ``seed`` for the tool ``pose`` into ``q_out``; a status code."""
    return _solve(dh, offsets, base_inv, tool_inv, limits, pose, seed, q_out, np.empty((6, 4)), np.empty(12))


@njit('void(float64[::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, :, ::1], '
      'float64[:, ::1], float64[:, ::1], int64[::1])', cache=True, nogil=True, error_model='numpy')
def solve_many(dh, offsets, base_inv, tool_inv, limits, poses, seeds, q_out, status_out):
    """:func:`solve` for every pose ``poses[i]`` from ``seeds[i]`` into ``q_out[i]``, ``status_out[i]``."""
    frames, angles = np.empty((6, 4)), np.empty(12)
    for i in range(poses.shape[0]):
        status_out[i] = _solve(dh, offsets, base_inv, tool_inv, limits, poses[i], seeds[i], q_out[i], frames, angles)
