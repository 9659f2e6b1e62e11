"""The chain's forward kinematics and the Jacobian's smallest singular value, compiled.

The fast path of :meth:`ArmModel.joint_frames` (and so of ``fk``) and of
:meth:`ArmModel.min_singular_values`, the two kinematic checks that every
Cartesian line or arc runs over its samples: the vectorised numpy versions
cost about 40 small array operations per joint and call (tens of microseconds
before any arithmetic), these a loop over configurations in machine code.
numba compiles them when this module is first imported and keeps the machine
code in its cache beside this file, as for :mod:`.fast_ik`.

The chain is packed in arrays (see :func:`pack`): each joint's fixed origin
(4x4, from its parent), its unit axis, whether it is prismatic (1.0 or 0.0),
and the tool's fixed transform from the last joint.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

# One signature each, compiled (or loaded from the cache) at import: a call with other types
# raises TypeError instead of compiling a new version in the middle of planning. Callers pass
# writable, aligned, C-contiguous float64 arrays (see ArmModel.joint_frames).
FRAMES = 'void(float64[:, :, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1], ' \
         'float64[:, :, :, ::1])'
#: Configurations whose Jacobians min_singular_values takes through Jacobi together (their
#: columns fit in the first-level cache).
BLOCK = 64
SINGULAR = 'void(float64[:, :, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1], ' \
           'int64, float64[::1])'


def pack(arm):
    """The chain of ``arm`` (an ArmModel) as the arrays the kernels take."""
    return (np.ascontiguousarray(arm._origins, dtype=float), np.ascontiguousarray(arm._axes, dtype=float),
            np.ascontiguousarray(arm._prismatic, dtype=float), np.ascontiguousarray(arm._tool, dtype=float))


class Bound:
    """The kernels bound to one arm: ``frames(q, out)`` and ``min_singular_values(q, rows, out)``."""

    def __init__(self, arm):
        model = pack(arm)
        self.frames = functools.partial(frames, *model)
        self.min_singular_values = functools.partial(min_singular_values, *model)


@njit(cache=True, nogil=True, error_model='numpy')
def _chain(origins, axes, prismatic, tool, q, out):
    """Frames of every joint (after its motion) and of the tool for one configuration ``q``
    into ``out`` (dof + 1, 4, 4).

    (Element by element: numba compiles array-slice assignments far more slowly.)
    """
    dof = q.size
    M = np.zeros((4, 4))                 # the joint's motion
    tmp = np.empty((4, 4))
    T = np.zeros((4, 4))
    for r in range(4):
        T[r, r] = M[r, r] = 1.0
    for i in range(dof):
        x, y, z = axes[i, 0], axes[i, 1], axes[i, 2]
        if prismatic[i] != 0.0:
            M[0, 0] = M[1, 1] = M[2, 2] = 1.0
            M[0, 1] = M[0, 2] = M[1, 0] = M[1, 2] = M[2, 0] = M[2, 1] = 0.0
            M[0, 3], M[1, 3], M[2, 3] = q[i] * x, q[i] * y, q[i] * z
        else:
            c, s = math.cos(q[i]), math.sin(q[i])
            C = 1.0 - c
            M[0, 0], M[0, 1], M[0, 2] = c + x * x * C, x * y * C - z * s, x * z * C + y * s
            M[1, 0], M[1, 1], M[1, 2] = y * x * C + z * s, c + y * y * C, y * z * C - x * s
            M[2, 0], M[2, 1], M[2, 2] = z * x * C - y * s, z * y * C + x * s, c + z * z * C
            M[0, 3] = M[1, 3] = M[2, 3] = 0.0
        # T = (T @ origin) @ motion, in the numpy version's order (the same rounding).
        _mul(T, origins[i], tmp)
        _mul(tmp, M, T)
        _copy(T, out[i])
    _mul(T, tool, out[dof])


@njit(cache=True, nogil=True, error_model='numpy')
def _mul(A, B, out):
    """out = A @ B for 4x4 transforms (their last rows 0 0 0 1)."""
    for r in range(3):
        a0, a1, a2, a3 = A[r, 0], A[r, 1], A[r, 2], A[r, 3]
        for c in range(4):
            out[r, c] = a0 * B[0, c] + a1 * B[1, c] + a2 * B[2, c] + a3 * B[3, c]
    out[3, 0] = out[3, 1] = out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True, nogil=True, error_model='numpy')
def _copy(A, out):
    for r in range(4):
        for c in range(4):
            out[r, c] = A[r, c]


@njit(cache=True, nogil=True, error_model='numpy')
def _jacobi_sweeps(A, width, alpha, beta, gamma, c, s):
    """One-sided Jacobi (Hestenes) on ``width`` matrices at once, overwriting them: ``A[p, i, k]``
    is row i of column p of matrix k. Plane rotations of column pairs until every pair of every
    matrix is orthogonal to working precision; the singular values are then the columns' norms.

    Small singular values come out with high relative accuracy (Demmel and Veselic 1992), and
    a 6 x 6 takes a few sweeps of 15 rotations. The matrices go in lockstep, the innermost loops
    over them (which the compiler vectorises: a third of the time of one matrix after another): a
    pair already orthogonal in one matrix is rotated by exactly the identity (c = 1, s = 0) while
    the others converge, so that each matrix ends exactly as it would alone. ``alpha`` .. ``s``:
    scratch of length >= width.
    """
    n = A.shape[0]
    m = A.shape[1]
    for _ in range(60):
        rotated = 0
        for p in range(n - 1):
            Ap = A[p]
            for q in range(p + 1, n):
                Aq = A[q]
                for k in range(width):
                    alpha[k] = beta[k] = gamma[k] = 0.0
                for i in range(m):
                    for k in range(width):
                        x, y = Ap[i, k], Aq[i, k]
                        alpha[k] += x * x
                        beta[k] += y * y
                        gamma[k] += x * y
                for k in range(width):
                    g = gamma[k]
                    done = abs(g) <= 1e-15 * math.sqrt(alpha[k] * beta[k]) or g == 0.0
                    zeta = (beta[k] - alpha[k]) / (2.0 * (1.0 if done else g))
                    t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                    t = 0.0 if done else t
                    rotated += 0 if done else 1
                    c[k] = 1.0 / math.sqrt(1.0 + t * t)
                    s[k] = c[k] * t
                for i in range(m):
                    for k in range(width):
                        x, y = Ap[i, k], Aq[i, k]
                        Ap[i, k] = c[k] * x - s[k] * y
                        Aq[i, k] = s[k] * x + c[k] * y
        if rotated == 0:
            return


@njit(cache=True, nogil=True, error_model='numpy')
def _smallest_column_norm(A, k, norms):
    """The smallest of the min(m, n) singular values of matrix ``k`` of :func:`_jacobi_sweeps`'s
    converged ``A`` (for n > m, n - m column norms are zero and not singular values)."""
    n, m = A.shape[0], A.shape[1]
    for j in range(n):
        acc = 0.0
        for i in range(m):
            acc += A[j, i, k] * A[j, i, k]
        norms[j] = math.sqrt(acc)
        i = j                            # insertion sort (numba's sort takes seconds to compile)
        while i > 0 and norms[i - 1] > norms[i]:
            norms[i - 1], norms[i] = norms[i], norms[i - 1]
            i -= 1
    return norms[n - min(m, n)]


@njit(FRAMES, cache=True, nogil=True, error_model='numpy')
def frames(origins, axes, prismatic, tool, q, out):
    """Joint and tool frames for every configuration: ``q`` (N, dof) -> ``out`` (N, dof + 1, 4, 4)."""
    for k in range(q.shape[0]):
        _chain(origins, axes, prismatic, tool, q[k], out[k])


@njit(SINGULAR, cache=True, nogil=True, error_model='numpy')
def min_singular_values(origins, axes, prismatic, tool, q, rows, out):
    """Smallest singular value of the geometric Jacobian's first ``rows`` rows (6: velocity
    and rotation, 3: velocity only) at every configuration ``q`` (N, dof) -> ``out`` (N,).

    One-sided Jacobi on J itself, BLOCK configurations at a time (see :func:`_jacobi_sweeps`):
    as accurate as numpy's SVD, where the Gram matrix J^T J would square the condition number
    (a singular configuration's 1e-17 would read as 1e-8).
    """
    n, dof = q.shape
    F = np.empty((dof + 1, 4, 4))
    size = max(min(BLOCK, n), 1)
    A = np.empty((dof, rows, size))
    scratch = np.empty((5, size))
    norms = np.empty(dof)
    for first in range(0, n, BLOCK):
        width = min(BLOCK, n - first)
        for k in range(width):
            _chain(origins, axes, prismatic, tool, q[first + k], F)
            for i in range(dof):
                zx = F[i, 0, 0] * axes[i, 0] + F[i, 0, 1] * axes[i, 1] + F[i, 0, 2] * axes[i, 2]
                zy = F[i, 1, 0] * axes[i, 0] + F[i, 1, 1] * axes[i, 1] + F[i, 1, 2] * axes[i, 2]
                zz = F[i, 2, 0] * axes[i, 0] + F[i, 2, 1] * axes[i, 1] + F[i, 2, 2] * axes[i, 2]
                J = A[i]
                if prismatic[i] != 0.0:
                    J[0, k], J[1, k], J[2, k] = zx, zy, zz
                    if rows > 3:
                        J[3, k] = J[4, k] = J[5, k] = 0.0
                else:
                    lx, ly, lz = F[dof, 0, 3] - F[i, 0, 3], F[dof, 1, 3] - F[i, 1, 3], F[dof, 2, 3] - F[i, 2, 3]
                    J[0, k], J[1, k], J[2, k] = zy * lz - zz * ly, zz * lx - zx * lz, zx * ly - zy * lx
                    if rows > 3:
                        J[3, k], J[4, k], J[5, k] = zx, zy, zz
        _jacobi_sweeps(A, width, scratch[0], scratch[1], scratch[2], scratch[3], scratch[4])
        for k in range(width):
            out[first + k] = _smallest_column_norm(A, k, norms)
