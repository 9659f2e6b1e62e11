"""Long samplings of a synchronised move, compiled: one pass that writes q, qd and qdd.

Where every joint of a segment follows one profile, ``q_j(tau) = c0_j + w_j s(tau)``
(see :func:`.piecewise._shared_profile`), a sampling of thousands of times costs
little more than writing its output (3 x n_joints doubles a sample): a cache-sized
chunk of ``s``, ``s'`` and ``s''`` is evaluated by Horner's scheme, then scaled
into each output row. numpy needs a dozen passes over the samples for the same
(the power basis, a small matrix product, the scaling and the start positions),
and the small product alone cost more than the output's write.

Imported by :mod:`.piecewise` only when a segment is sampled at thousands of
times (never by a controller's per-tick sampling), so no process loads numba for
short samplings. numba compiles it when this module is first imported and keeps
the machine code in its cache beside this file, as for the kinematics' kernels;
``make`` builds that cache when it installs.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

_IN = types.Array(types.float64, 1, 'A', readonly=True)
_PROFILE = types.Array(types.float64, 2, 'C', readonly=True)
_OUT = types.Array(types.float64, 2, 'A')
# One signature, compiled (or loaded from the cache) at import: a call with other types raises
# TypeError instead of compiling a new version in the middle of sampling.
SIGNATURE = types.void(_IN, types.float64, types.float64, types.float64, types.boolean,
                       _PROFILE, _IN, _IN, _OUT)

#: Samples per chunk: the chunk's profile (3 x 2048 doubles, 48 KiB) stays in cache.
CHUNK = 2048


@njit(SIGNATURE, cache=True, nogil=True, error_model='numpy')
def sample_shared(t, lo, hi, origin, clip, profile, w, c0, out):
    """Write q, qd, qdd at times ``t`` into ``out`` (3n, len(t)), rows q then qd then qdd.

    ``profile`` (3, 6): power-basis coefficients of ``s``, ``s'`` and ``s''`` in local time
    ``tau = t - origin``, the time first clipped to ``[lo, hi]`` if ``clip``; ``w`` (n,) the
    joints' scales; ``c0`` (n,) their positions at ``tau = 0``.
    """
    n = w.size
    size = t.size
    s = np.empty((3, CHUNK))
    for a in range(0, size, CHUNK):
        m = min(CHUNK, size - a)
        for k in range(m):
            x = t[a + k]
            if clip:
                x = min(max(x, lo), hi)
            x -= origin
            for r in range(3):
                c = profile[r]
                s[r, k] = ((((c[5] * x + c[4]) * x + c[3]) * x + c[2]) * x + c[1]) * x + c[0]
        for j in range(n):
            wj = w[j]
            cj = c0[j]
            dst = out[j, a:a + m]
            src = s[0]
            for k in range(m):
                dst[k] = cj + wj * src[k]
            for r in range(1, 3):
                dst = out[r * n + j, a:a + m]
                src = s[r]
                for k in range(m):
                    dst[k] = wj * src[k]
