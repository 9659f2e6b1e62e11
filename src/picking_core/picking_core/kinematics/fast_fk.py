"""The chain's forward kinematics and the Jacobian's smallest singular value, compiled.

The fast path of :meth:`ArmModel.joint_frames`, of ``fk`` and of
:meth:`ArmModel.min_singular_values`, the two kinematic checks that every
Cartesian line or arc runs over its samples: the vectorised numpy versions
cost about 40 small array operations per joint and call (tens of microseconds
before any arithmetic), these loops in machine code. They take BLOCK
configurations at a time, each product over the configurations innermost,
which the compiler turns into vector instructions (several configurations per
instruction). numba compiles them when this module is first imported and keeps
the machine code in its cache beside this file, as for :mod:`.fast_ik`.

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
SINGULAR = 'void(float64[:, :, ::1], float64[:, ::1], float64[::1], float64[:, ::1], float64[:, ::1], ' \
           'int64, float64[::1])'


#: Configurations that the kernels take together (their frames and Jacobians fit in the
#: first-level cache).
BLOCK = 64


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
def _chain_block(origins, axes, prismatic, tool, q, first, width, F, A, cs):
    """Frames of every joint (after its motion) and of the tool for the ``width`` configurations
    from ``q[first]`` into ``F`` (dof + 1, 3, 4, >= width): ``F[i, r, c, k]`` is row r, column c
    of joint i's frame (i = dof: the tool's) in configuration ``first + k``; the last row of
    every frame is 0 0 0 1. ``A`` (3, 4, >= width) and ``cs`` (2, >= width): scratch.

    Each joint's frame is the one before it times the joint's fixed origin times its motion,
    in the numpy version's order (the same rounding); the configurations are the innermost
    loop of every product. (Element by element: numba compiles array-slice assignments far
    more slowly.)
    """
    dof = q.shape[1]
    for i in range(dof):
        O = origins[i]
        if i == 0:                        # the base frame is the identity
            for r in range(3):
                for c in range(4):
                    for k in range(width):
                        A[r, c, k] = O[r, c]
        else:
            _times(F[i - 1], O, width, A)
        x, y, z = axes[i, 0], axes[i, 1], axes[i, 2]
        T = F[i]
        if prismatic[i] != 0.0:
            for r in range(3):
                for k in range(width):
                    d = q[first + k, i]
                    T[r, 0, k], T[r, 1, k], T[r, 2, k] = A[r, 0, k], A[r, 1, k], A[r, 2, k]
                    T[r, 3, k] = A[r, 0, k] * (d * x) + A[r, 1, k] * (d * y) + A[r, 2, k] * (d * z) + A[r, 3, k]
            continue
        for k in range(width):            # the calls apart: the products below vectorise
            cs[0, k] = math.cos(q[first + k, i])
            cs[1, k] = math.sin(q[first + k, i])
        for k in range(width):
            c, s = cs[0, k], cs[1, k]
            C = 1.0 - c
            m00, m01, m02 = c + x * x * C, x * y * C - z * s, x * z * C + y * s
            m10, m11, m12 = y * x * C + z * s, c + y * y * C, y * z * C - x * s
            m20, m21, m22 = z * x * C - y * s, z * y * C + x * s, c + z * z * C
            for r in range(3):
                a0, a1, a2 = A[r, 0, k], A[r, 1, k], A[r, 2, k]
                T[r, 0, k] = a0 * m00 + a1 * m10 + a2 * m20
                T[r, 1, k] = a0 * m01 + a1 * m11 + a2 * m21
                T[r, 2, k] = a0 * m02 + a1 * m12 + a2 * m22
                T[r, 3, k] = A[r, 3, k]
    _times(F[dof - 1], tool, width, F[dof])


@njit(cache=True, nogil=True, error_model='numpy')
def _times(P, B, width, out):
    """``out = P @ B`` for the ``width`` transforms of ``P`` (3, 4, >= width), laid out as in
    :func:`_chain_block`, and one 4x4 transform ``B``."""
    for r in range(3):
        for c in range(4):
            b0, b1, b2, b3 = B[0, c], B[1, c], B[2, c], B[3, c]
            for k in range(width):
                out[r, c, k] = P[r, 0, k] * b0 + P[r, 1, k] * b1 + P[r, 2, k] * b2 + P[r, 3, k] * b3


@njit(cache=True, nogil=True, error_model='numpy')
def _scratch(n, dof):
    """The chain's arrays for ``n`` configurations (see :func:`_chain_block`)."""
    size = max(min(BLOCK, n), 1)
    return np.empty((dof + 1, 3, 4, size)), np.empty((3, 4, size)), np.empty((2, size))


@njit(cache=True, nogil=True, error_model='numpy')
def _unpack(F, i, k, out):
    """Frame ``i`` of configuration ``k`` of a block (see :func:`_chain_block`) as a 4x4 ``out``."""
    for r in range(3):
        for c in range(4):
            out[r, c] = F[i, r, c, k]
    out[3, 0] = out[3, 1] = out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True, nogil=True, error_model='numpy')
def _jacobi_sweeps(A, width, alpha, beta, gamma, c, s):
    """One-sided Jacobi (Hestenes) on ``width`` matrices at once, overwriting them: ``A[p, i, k]``
    is row i of column p of matrix k. Plane rotations of column pairs until every pair of every
    matrix is orthogonal to working precision; the singular values are then the columns' norms.

    Small singular values come out with high relative accuracy (Demmel and Veselic 1992), and
    a 6 x 6 takes a few sweeps of 15 rotations. The matrices go in lockstep, the innermost loops
    over them (which the compiler vectorises: 0.4 of the time of one matrix after another): a
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
    """The last k frames of the chain (every joint's after its motion, then the tool's) for every
    configuration: ``q`` (N, dof) -> ``out`` (N, k, 4, 4); k = dof + 1 gives them all, k = 1 the
    tool's alone (forward kinematics)."""
    n, dof = q.shape
    skip = dof + 1 - out.shape[1]
    F, A, cs = _scratch(n, dof)
    for first in range(0, n, BLOCK):
        width = min(BLOCK, n - first)
        _chain_block(origins, axes, prismatic, tool, q, first, width, F, A, cs)
        for k in range(width):
            for i in range(out.shape[1]):
                _unpack(F, skip + i, k, out[first + k, i])


@njit(SINGULAR, cache=True, nogil=True, error_model='numpy')
def min_singular_values(origins, axes, prismatic, tool, q, rows, out):
    """Smallest singular value of the geometric Jacobian's first ``rows`` rows (6: velocity
    and rotation, 3: velocity only) at every configuration ``q`` (N, dof) -> ``out`` (N,).

    One-sided Jacobi on J itself, BLOCK configurations at a time (see :func:`_jacobi_sweeps`):
    as accurate as numpy's SVD, where the Gram matrix J^T J would square the condition number
    (a singular configuration's 1e-17 would read as 1e-8).
    """
    n, dof = q.shape
    F, A, cs = _scratch(n, dof)
    J = np.empty((dof, rows, F.shape[3]))           # J[i, r, k]: row r of column i, configuration k
    scratch = np.empty((5, F.shape[3]))
    norms = np.empty(dof)
    tip = F[dof]
    for first in range(0, n, BLOCK):
        width = min(BLOCK, n - first)
        _chain_block(origins, axes, prismatic, tool, q, first, width, F, A, cs)
        for i in range(dof):
            x, y, z = axes[i, 0], axes[i, 1], axes[i, 2]
            R, col = F[i], J[i]
            for k in range(width):
                zx = R[0, 0, k] * x + R[0, 1, k] * y + R[0, 2, k] * z
                zy = R[1, 0, k] * x + R[1, 1, k] * y + R[1, 2, k] * z
                zz = R[2, 0, k] * x + R[2, 1, k] * y + R[2, 2, k] * z
                if prismatic[i] != 0.0:
                    col[0, k], col[1, k], col[2, k] = zx, zy, zz
                    if rows > 3:
                        col[3, k] = col[4, k] = col[5, k] = 0.0
                else:
                    lx, ly, lz = tip[0, 3, k] - R[0, 3, k], tip[1, 3, k] - R[1, 3, k], tip[2, 3, k] - R[2, 3, k]
                    col[0, k], col[1, k], col[2, k] = zy * lz - zz * ly, zz * lx - zx * lz, zx * ly - zy * lx
                    if rows > 3:
                        col[3, k], col[4, k], col[5, k] = zx, zy, zz
        _jacobi_sweeps(J, width, scratch[0], scratch[1], scratch[2], scratch[3], scratch[4])
        for k in range(width):
            out[first + k] = _smallest_column_norm(J, k, norms)
