"""Samplings compiled: long ones of a synchronised move, and short ones of many segments.

:func:`sample_shared`: one pass that writes q, qd and qdd of a synchronised move.

Where every joint of a segment follows one profile, ``q_j(tau) = c0_j + w_j s(tau)``
(see :func:`.piecewise._shared_profile`), a sampling of thousands of times costs
little more than writing its output (3 x n_joints doubles a sample): a cache-sized
chunk of ``s``, ``s'`` and ``s''`` is evaluated by Horner's scheme, then scaled
into each output row, every loop over contiguous memory so that LLVM vectorises
it. numpy needs a dozen passes over the samples for the same (the power basis, a
small matrix product, the scaling and the start positions), and the small product
alone cost more than the output's write.

:func:`sample_pieces`: a trajectory of many segments (a spline through a line's IK
samples, a whole pick cycle) at up to a few thousand times, each sample's segment
found by bisection and its q, qd and qdd evaluated by Horner's scheme, where numpy
needs a dozen calls (search, clip, gather, power basis, a batched product of
tiny matrices) of 5-20 µs each.

Imported by :mod:`.piecewise` when a segment is sampled at thousands of times, and
for short samplings only in a process that asked for them (a planner: see
:func:`.piecewise.use_compiled_sampling`), so that a controller never stalls on
numba's import. numba compiles it when this module is first imported and keeps
the machine code in its cache beside this file, as for the kinematics' kernels;
``make`` builds that cache when it installs.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

_IN = types.Array(types.float64, 1, 'C', readonly=True)
_PROFILE = types.Array(types.float64, 2, 'C', readonly=True)
_OUT = types.Array(types.float64, 2, 'C')
# One signature, compiled (or loaded from the cache) at import: a call with other types raises
# TypeError instead of compiling a new version in the middle of sampling. Contiguous arrays
# only: with unknown strides ('A') or an index computed in the inner loop, LLVM does not
# vectorise the loops, and the kernel took 3x as long (0.65-0.77 ms against 0.21 ms for
# 100 000 x 6 samples on an AVX-512 machine, where numpy's fill of the output takes 0.21 ms).
SIGNATURE = types.void(_IN, types.float64, types.float64, types.float64, types.boolean,
                       _PROFILE, _IN, _IN, _OUT, types.intp)

#: Samples per chunk: the chunk's profile (3 x 2048 doubles, 48 KiB) stays in cache.
CHUNK = 2048


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def sample_shared(t, lo, hi, origin, clip, profile, w, c0, out, col):
    """Write q, qd, qdd at times ``t`` into ``out[:, col:col + len(t)]`` (out: 3n rows, q then
    qd then qdd).

    ``profile`` (3, 6): power-basis coefficients of ``s``, ``s'`` and ``s''`` in local time
    ``tau = t - origin``, the time first clipped to ``[lo, hi]`` if ``clip``; ``w`` (n,) the
    joints' scales; ``c0`` (n,) their positions at ``tau = 0``.
    """
    n = w.size
    size = t.size
    s = np.empty((3, CHUNK))
    for a in range(0, size, CHUNK):
        m = min(CHUNK, size - a)
        times = t[a:a + m]
        for r in range(3):
            c5, c4, c3, c2, c1, c = profile[r, 5], profile[r, 4], profile[r, 3], profile[r, 2], profile[r, 1], \
                profile[r, 0]
            sr = s[r]
            for k in range(m):
                x = times[k]
                if clip:
                    x = min(max(x, lo), hi)
                x -= origin
                sr[k] = ((((c5 * x + c4) * x + c3) * x + c2) * x + c1) * x + c
        for r in range(3):
            src = s[r]
            for j in range(n):
                wj = w[j]
                cj = c0[j] if r == 0 else 0.0
                dst = out[r * n + j][col + a:col + a + m]
                for k in range(m):
                    dst[k] = cj + wj * src[k]


_ROWS = types.Array(types.float64, 3, 'C', readonly=True)
PIECES = types.void(_IN, _ROWS, _IN, _OUT)


@njit(PIECES, cache=True, nogil=True, error_model='numpy')
def sample_pieces(breaks, rows, t, out):
    """Write q, qd, qdd at times ``t`` (any order) into ``out`` (3n rows, q then qd then qdd,
    one column per time).

    ``rows`` (m, 3n, 6): each segment's power-basis coefficients of q, qd and qdd in its
    local time. Segment ``k`` covers ``(breaks[k], breaks[k + 1]]`` (the first one its start
    too); a time before the start holds the first point, after the end the last, at rest.
    """
    m = breaks.size - 1
    rows_per_sample = out.shape[0]
    n = rows_per_sample // 3
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
        c = rows[lo]
        for r in range(n if held else rows_per_sample):
            out[r, i] = ((((c[r, 5] * tau + c[r, 4]) * tau + c[r, 3]) * tau + c[r, 2]) * tau + c[r, 1]) * tau \
                + c[r, 0]
        if held:
            for r in range(n, rows_per_sample):
                out[r, i] = 0.0
