"""Numeric IK for any serial chain, compiled: Levenberg-Marquardt within the joint limits.

The fast path of :class:`.solvers.NumericSolver`. From the seed first, then
from a fixed sequence of random starts within the limits, each step solves
``(J J^T + lambda I) y = e``, moves ``J^T y`` (no joint further than
:data:`MAX_STEP`) and clips to the limits; a step that does not lower the error
is taken back and the damping raised tenfold, one that does lowers it. A
solution is accepted when the position is within :data:`TOLERANCE` m and the
orientation within :data:`TOLERANCE` rad (the position alone for arms of fewer
than six joints). Starting at the seed keeps a redundant arm's solution near it.

Status codes and input checks are :mod:`.fast_ik`'s; a pose farther from the first
joint than the chain is long is ``OUT_OF_REACH`` (proven), one no start
converged on ``NO_SOLUTION`` (not proven unreachable). The chain is packed as in
:mod:`.fast_fk`, with ``limits`` (rows lower, upper, revolute flag) and
``settings``: rows solved (3 or 6), restarts, iterations per start, the first
joint's position (x, y, z) and the chain's length.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fast_fk import _chain_block
from .fast_fk import pack as pack_chain
from .fast_ik import NO_SOLUTION, OK, OUT_OF_REACH, Bound, check_inputs

TOLERANCE = 1e-10
MAX_STEP = 0.5          # rad (m) a joint moves at most per step: far starts do not overshoot
SEED_BUDGET = 4         # the start at the seed may take this many times the iterations of a random one
_RESTART_SEED = 20260  # the random starts are the same for every pose: answers are reproducible


def pack(solver):
    arm = solver.arm
    limits = np.array([arm.lower, arm.upper, 1.0 - arm._prismatic], dtype=float)
    settings = np.array([3 if solver.position_only else 6, solver.restarts, solver.iterations,
                         *solver.base_point, solver.reach[1]], dtype=float)
    return (*pack_chain(arm), limits, settings)


def bind(solver):
    """This module's kernels bound to ``solver``'s arm (:class:`.fast_ik.Bound`)."""
    return Bound(pack(solver), solve, solve_many)


@njit(cache=True, nogil=True, error_model='numpy')
def _error(F, dof, pose, rows, e):
    """The tool's error ``e`` (position, then rotation vector) against ``pose``; its norm."""
    for r in range(3):
        e[r] = pose[r, 3] - F[dof, r, 3, 0]
    if rows == 6:
        # R = pose R_tool^T, then its rotation vector (log map), robust near half a turn.
        R = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                R[i, j] = pose[i, 0] * F[dof, j, 0, 0] + pose[i, 1] * F[dof, j, 1, 0] + pose[i, 2] * F[dof, j, 2, 0]
        vx, vy, vz = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
        s = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
        c = max(-1.0, min(1.0, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)))
        angle = math.atan2(s, c)
        if angle < 1e-6:
            k = 0.5
        elif angle < math.pi - 1e-3:
            k = angle / (2.0 * s)
        else:
            # Near half a turn the axis is the largest column of (R + I) / 2.
            m = 0
            for i in range(1, 3):
                if R[i, i] > R[m, m]:
                    m = i
            d = math.sqrt(max(0.5 * (R[m, m] + 1.0), 1e-300))
            ax = np.empty(3)
            for i in range(3):
                ax[i] = d if i == m else 0.25 * (R[i, m] + R[m, i]) / d
            flip = -1.0 if ax[0] * vx + ax[1] * vy + ax[2] * vz < 0.0 else 1.0
            vx, vy, vz = flip * ax[0], flip * ax[1], flip * ax[2]
            k = angle
        e[3], e[4], e[5] = k * vx, k * vy, k * vz
    total = 0.0
    for r in range(rows):
        total += e[r] * e[r]
    return math.sqrt(total)


@njit(cache=True, nogil=True, error_model='numpy')
def _step(F, axes, prismatic, dof, rows, e, lam, dq):
    """The damped least-squares step for the error ``e`` at the frames ``F`` into ``dq``."""
    J = np.zeros((6, dof))
    px, py, pz = F[dof, 0, 3, 0], F[dof, 1, 3, 0], F[dof, 2, 3, 0]
    for i in range(dof):
        z = np.empty(3)
        for r in range(3):
            z[r] = F[i, r, 0, 0] * axes[i, 0] + F[i, r, 1, 0] * axes[i, 1] + F[i, r, 2, 0] * axes[i, 2]
        if prismatic[i] != 0.0:
            J[0, i], J[1, i], J[2, i] = z[0], z[1], z[2]
        else:
            dx, dy, dz = px - F[i, 0, 3, 0], py - F[i, 1, 3, 0], pz - F[i, 2, 3, 0]
            J[0, i], J[1, i], J[2, i] = z[1] * dz - z[2] * dy, z[2] * dx - z[0] * dz, z[0] * dy - z[1] * dx
            J[3, i], J[4, i], J[5, i] = z[0], z[1], z[2]
    # (J J^T + lam I) y = e by Cholesky.
    M = np.empty((rows, rows))
    for a in range(rows):
        for b in range(a + 1):
            acc = 0.0
            for i in range(dof):
                acc += J[a, i] * J[b, i]
            M[a, b] = acc + (lam if a == b else 0.0)
    for a in range(rows):
        for b in range(a + 1):
            acc = M[a, b]
            for k in range(b):
                acc -= M[a, k] * M[b, k]
            M[a, b] = math.sqrt(max(acc, 1e-300)) if a == b else acc / M[b, b]
    y = np.empty(rows)
    for a in range(rows):
        acc = e[a]
        for k in range(a):
            acc -= M[a, k] * y[k]
        y[a] = acc / M[a, a]
    for a in range(rows - 1, -1, -1):
        acc = y[a]
        for k in range(a + 1, rows):
            acc -= M[k, a] * y[k]
        y[a] = acc / M[a, a]
    biggest = 0.0
    for i in range(dof):
        acc = 0.0
        for a in range(rows):
            acc += J[a, i] * y[a]
        dq[i] = acc
        biggest = max(biggest, abs(acc))
    if biggest > MAX_STEP:
        for i in range(dof):
            dq[i] *= MAX_STEP / biggest


SIGNATURE = ('int64(float64[:, :, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1], '
             'float64[::1], float64[:, ::1], float64[::1], float64[::1])')


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def solve(origins, axes, prismatic, tool, limits, settings, pose, seed, q_out):
    """A solution for the tool ``pose`` from ``seed`` into ``q_out``; a status code."""
    status = check_inputs(pose, seed)
    if status != OK:
        return status
    rows, restarts, iterations = int(settings[0]), int(settings[1]), int(settings[2])
    dx, dy, dz = pose[0, 3] - settings[3], pose[1, 3] - settings[4], pose[2, 3] - settings[5]
    if math.sqrt(dx * dx + dy * dy + dz * dz) > settings[6] + 1e-9:
        return OUT_OF_REACH
    dof = seed.shape[0]
    F, A, cs = np.empty((dof + 1, 3, 4, 1)), np.empty((3, 4, 1)), np.empty((2, 1))
    Ft = np.empty((dof + 1, 3, 4, 1))
    q, trial, dq = np.empty((1, dof)), np.empty((1, dof)), np.empty(dof)
    e, et = np.empty(6), np.empty(6)
    np.random.seed(_RESTART_SEED)
    for start in range(restarts + 1):
        for j in range(dof):
            lo, hi = limits[0, j], limits[1, j]
            if start == 0:
                v = seed[j]
            else:
                v = np.random.uniform(lo if math.isfinite(lo) else -math.pi, hi if math.isfinite(hi) else math.pi)
            q[0, j] = min(max(v, lo), hi)
        _chain_block(origins, axes, prismatic, tool, q, 0, 1, F, A, cs)
        err = _error(F, dof, pose, rows, e)
        lam = 1e-3
        for _ in range(iterations * SEED_BUDGET if start == 0 else iterations):
            if err < TOLERANCE:
                for j in range(dof):
                    q_out[j] = q[0, j]
                return OK
            _step(F, axes, prismatic, dof, rows, e, lam, dq)
            for j in range(dof):
                trial[0, j] = min(max(q[0, j] + dq[j], limits[0, j]), limits[1, j])
            _chain_block(origins, axes, prismatic, tool, trial, 0, 1, Ft, A, cs)
            err_trial = _error(Ft, dof, pose, rows, et)
            if err_trial < err:
                q, trial = trial, q
                F, Ft = Ft, F
                e, et = et, e
                err = err_trial
                lam = max(lam * 0.3, 1e-12)
            else:
                lam *= 10.0
                if lam > 1e4:
                    break                 # stuck (a limit or a local minimum): the next start
        if err < TOLERANCE:
            for j in range(dof):
                q_out[j] = q[0, j]
            return OK
    return NO_SOLUTION


@njit('void(float64[:, :, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[::1], '
      'float64[:, :, ::1], float64[:, ::1], float64[:, ::1], int64[::1])', cache=True, nogil=True, error_model='numpy')
def solve_many(origins, axes, prismatic, tool, limits, settings, poses, seeds, q_out, status_out):
    """:func:`solve` for every pose ``poses[i]`` from ``seeds[i]`` into ``q_out[i]``, ``status_out[i]``."""
    for i in range(poses.shape[0]):
        status_out[i] = solve(origins, axes, prismatic, tool, limits, settings, poses[i], seeds[i], q_out[i])
