"""Long samplings of a synchronised move, compiled: one pass that writes q, qd and qdd.

Where every joint of a segment follows one profile, ``q_j(tau) = c0_j + w_j s(tau)``
(see :func:`.piecewise._shared_profile`), a sampling of thousands of times costs
little more than writing its output (3 x n_joints doubles a sample): a cache-sized
chunk of ``s``, ``s'`` and ``s''`` is evaluated by Horner's scheme, then scaled
into each output row, every loop over contiguous memory so that LLVM vectorises
it. numpy needs a dozen passes over the samples for the same (the power basis, a
small matrix product, the scaling and the start positions), and the small product
alone cost more than the output's write.

Imported by :mod:`.piecewise` only when a segment is sampled at thousands of
times (never by a controller's per-tick sampling), so no process loads numba for
short samplings. numba compiles it when this module is first imported and keeps
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
