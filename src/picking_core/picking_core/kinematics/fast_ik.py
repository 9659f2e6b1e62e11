"""The closed-form IK, compiled: the fast path of :meth:`ArmModel.ik` and :meth:`ArmModel.ik_batch`.

The same solutions as the vectorised closed forms of :mod:`.solvers` (every
branch, each joint moved to its 2 pi image nearest the seed within the limits,
the valid solution nearest the seed), in one compiled function: the pose and
seed checks, the 4 arm branches and the 2 wrist flips of each run without a
Python object in between; :func:`solve_many` runs it over a batch. numba compiles it when this module is first imported
(about 2 s) and keeps the machine code in its cache beside this file
(``__pycache__``), so later processes load it in a fraction of a second; ``make``
builds that cache when it installs.

Everything is checked in the compiled code and reported as a status code, so
that the caller raises the same errors as the vectorised path. The model is
packed in arrays (see :func:`pack`):

- ``geometry``: shoulder position x, y, z (m), upper-arm and forearm lengths (m);
- ``tool_inv``: the inverse of the flange-to-tool transform (identity for the
  position-only 3-joint arm, whose "forearm" ends at the tool point);
- ``limits``: rows lower, upper, revolute flag (1 or 0), one column per joint.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

OK, NOT_FINITE, NOT_ROTATION, BAD_SEED, OUT_OF_REACH, BEYOND_LIMITS, NO_SOLUTION = range(7)

_TWO_PI = 2.0 * math.pi
_TOL = 1e-9           # the vectorised path's limit tolerance
_SINGULAR = 1e-9      # |sin q5| below which the wrist is singular
_ROTATION_TOL = 1e-6  # the pose check of ArmModel (orthonormal rows, det > 0)


def pack(solver):
    """The closed-form solver's model as the arrays the kernel takes."""
    arm = solver.arm
    geometry = np.array([*solver.shoulder, solver.l2, solver.l3], dtype=float)
    tool_inv = np.ascontiguousarray(getattr(solver, 'tool_inv', np.eye(4)), dtype=float)
    limits = np.array([arm.lower, arm.upper, solver.revolute], dtype=float)
    return geometry, tool_inv, limits


class Bound:
    """Kernels bound to one arm's packed ``model``: ``one(pose, seed, q_out) -> status`` and
    ``many(poses, seeds, q_out, status_out)`` (every compiled IK module has this pair)."""

    def __init__(self, model, solve, solve_many):
        self.one = functools.partial(solve, *model)
        self.many = functools.partial(solve_many, *model)


def bind(solver):
    """This module's kernels bound to ``solver``'s arm."""
    return Bound(pack(solver), solve, solve_many)


@njit(cache=True, nogil=True, error_model='numpy')
def image(v, s, lo, hi, revolute):
    """(v moved by 2 pi turns into [lo, hi] nearest s, True), or (v, False) if it cannot be."""
    if revolute:
        v += _TWO_PI * math.floor((s - v) / _TWO_PI + 0.5)
    if lo - _TOL <= v <= hi + _TOL:
        return v, True
    if revolute:
        step = _TWO_PI if s >= v else -_TWO_PI
        if lo - _TOL <= v + step <= hi + _TOL:
            return v + step, True
        if lo - _TOL <= v - step <= hi + _TOL:
            return v - step, True
    return v, False


@njit(cache=True, nogil=True, error_model='numpy')
def check_inputs(pose, seed):
    """OK, or the status code of a non-finite pose or seed or a pose whose rotation is not proper."""
    for i in range(4):
        for j in range(4):
            if not math.isfinite(pose[i, j]):
                return NOT_FINITE
    for j in range(seed.shape[0]):
        if not math.isfinite(seed[j]):
            return BAD_SEED
    worst = 0.0
    for i in range(3):
        for k in range(i, 3):
            dot = pose[i, 0] * pose[k, 0] + pose[i, 1] * pose[k, 1] + pose[i, 2] * pose[k, 2]
            worst = max(worst, abs(dot - 1.0) if i == k else abs(dot))
    det = (pose[0, 0] * (pose[1, 1] * pose[2, 2] - pose[1, 2] * pose[2, 1])
           - pose[0, 1] * (pose[1, 0] * pose[2, 2] - pose[1, 2] * pose[2, 0])
           + pose[0, 2] * (pose[1, 0] * pose[2, 1] - pose[1, 1] * pose[2, 0]))
    if worst > _ROTATION_TOL or det < 0.0:
        return NOT_ROTATION
    return OK


# One signature, compiled (or loaded from the cache) at import: a call with other types raises
# TypeError instead of compiling a new version in the middle of planning (seconds). Callers pass
# writable, aligned, C-contiguous float64 arrays (see ArmModel.ik).
SIGNATURE = 'int64(float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[::1], float64[::1])'


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def solve(geometry, tool_inv, limits, pose, seed, q_out):
    """The valid solution nearest ``seed`` for the tool ``pose`` into ``q_out``; a status code.

    ``seed`` has 3 joints (position only: waist, shoulder, elbow) or 6 (and a
    z-y-z spherical wrist).
    """
    status = check_inputs(pose, seed)
    if status != OK:
        return status
    dof = seed.shape[0]

    # The flange (wrist centre at its origin): the pose times the inverse tool transform.
    F = np.empty((3, 4))
    for i in range(3):
        for j in range(4):
            F[i, j] = (pose[i, 0] * tool_inv[0, j] + pose[i, 1] * tool_inv[1, j]
                       + pose[i, 2] * tool_inv[2, j] + pose[i, 3] * tool_inv[3, j])

    # Waist, shoulder and elbow: two waist angles (front, back) times two elbow signs.
    l2, l3 = geometry[3], geometry[4]
    x, y, z = F[0, 3] - geometry[0], F[1, 3] - geometry[1], F[2, 3] - geometry[2]
    rho = math.hypot(x, y)
    D = (rho * rho + z * z - l2 * l2 - l3 * l3) / (2.0 * l2 * l3)
    if abs(D) > 1.0 + 1e-12:
        return OUT_OF_REACH
    q1_front = seed[0] if rho < _TOL else math.atan2(y, x)
    q3_up = math.acos(max(-1.0, min(1.0, D)))

    best = math.inf
    cand = np.empty(dof)
    for back in range(2):
        q1 = q1_front + math.pi if back else q1_front
        r = -rho if back else rho
        for down in range(2):
            q3 = -q3_up if down else q3_up
            q2 = math.atan2(r, z) - math.atan2(l3 * math.sin(q3), l2 + l3 * math.cos(q3))
            cand[0], cand[1], cand[2] = q1, q2, q3
            head, ok = 0.0, True
            for j in range(3):
                cand[j], ok = image(cand[j], seed[j], limits[0, j], limits[1, j], limits[2, j])
                if not ok:
                    break
                head += (cand[j] - seed[j]) ** 2
            if not ok or head >= best:
                continue
            if dof == 3:
                best = head
                for j in range(3):
                    q_out[j] = cand[j]
                continue

            # The wrist: R36 = (Rz(q1) Ry(q2 + q3))^T R06 as z-y-z angles; only five entries needed.
            c1, s1 = math.cos(q1), math.sin(q1)
            c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
            a0, a1, a2 = c1 * c23, s1 * c23, -s23
            e0, e1, e2 = c1 * s23, s1 * s23, c23
            r02 = a0 * F[0, 2] + a1 * F[1, 2] + a2 * F[2, 2]
            r12 = -s1 * F[0, 2] + c1 * F[1, 2]
            r22 = e0 * F[0, 2] + e1 * F[1, 2] + e2 * F[2, 2]
            r20 = e0 * F[0, 0] + e1 * F[1, 0] + e2 * F[2, 0]
            r21 = e0 * F[0, 1] + e1 * F[1, 1] + e2 * F[2, 1]
            s5 = math.hypot(r02, r12)
            q5 = math.atan2(s5, r22)
            if s5 < _SINGULAR:
                # Only q4 + q6 (q4 - q6 when q5 = pi) is defined: keep q4 at the seed.
                r00 = a0 * F[0, 0] + a1 * F[1, 0] + a2 * F[2, 0]
                r10 = -s1 * F[0, 0] + c1 * F[1, 0]
                r01 = a0 * F[0, 1] + a1 * F[1, 1] + a2 * F[2, 1]
                r11 = -s1 * F[0, 1] + c1 * F[1, 1]
                q4 = seed[3]
                q6 = math.atan2(r10, r00) - q4 if r22 > 0.0 else q4 - math.atan2(-r01, r11)
            else:
                q4 = math.atan2(r12, r02)
                q6 = math.atan2(r21, -r20)
            for flip in range(2):
                if flip:
                    cand[3], cand[4], cand[5] = q4 + math.pi, -q5, q6 + math.pi
                else:
                    cand[3], cand[4], cand[5] = q4, q5, q6
                dist = head
                for j in range(3, 6):
                    cand[j], ok = image(cand[j], seed[j], limits[0, j], limits[1, j], limits[2, j])
                    if not ok:
                        break
                    dist += (cand[j] - seed[j]) ** 2
                if ok and dist < best:
                    best = dist
                    for j in range(6):
                        q_out[j] = cand[j]
    return OK if best < math.inf else BEYOND_LIMITS


@njit('void(float64[::1], float64[:, ::1], float64[:, ::1], float64[:, :, ::1], float64[:, ::1], float64[:, ::1], '
      'int64[::1])', cache=True, nogil=True, error_model='numpy')
def solve_many(geometry, tool_inv, limits, poses, seeds, q_out, status_out):
    """:func:`solve` for every pose ``poses[i]`` from ``seeds[i]`` into ``q_out[i]``, ``status_out[i]``."""
    for i in range(poses.shape[0]):
        status_out[i] = solve(geometry, tool_inv, limits, poses[i], seeds[i], q_out[i])
