"""One representation for every time profile: a piecewise polynomial in time.

Cubic and quintic moves are one segment; LSPB is three (blend, cruise, blend);
via-point LSPB and quintic splines are many. All of them share one sampler, so
composition (``then``, ``concatenate``) and vectorised sampling come for free.

Segment ``k`` covers ``[breaks[k], breaks[k+1]]`` and is stored in local time
``tau = t - breaks[k]`` in the power basis::

    q(t) = sum_i coeffs[k, i, j] * tau**i        for joint j

Units are whatever the caller used for positions (rad, m, or degrees in the
paper's examples); time is in seconds.
"""

from __future__ import annotations

import functools
from bisect import bisect_left

import numpy as np

from ..compiled import load
from ._checks import as_duration, as_joint_vector, as_time_array, time_array_and_extremes

#: Largest polynomial degree stored (quintic).
MAX_DEGREE = 5
_N_COEFFS = MAX_DEGREE + 1

# Factors that turn power-basis coefficients into those of the first and
# second derivative: d/dtau sum c_i tau^i = sum i c_i tau^(i-1).
_D1 = np.arange(1, _N_COEFFS, dtype=float)
_D2 = _D1[1:] * np.arange(1, _N_COEFFS - 1, dtype=float)
# Above this many segments, sample() gathers each sample's coefficients instead of looping
# (up to this many samples at once: the gathered copy grows with both).
_GATHER_SEGMENTS = 8
_GATHER_SAMPLES = 20_000
# Samples evaluated at once by one segment's matrix product: the power basis of a chunk
# (6 x 8192 doubles, 384 KiB) stays in cache.
_CHUNK = 8192
# From this many samples of one segment on, sample() looks for a profile all its joints share
# (a few microseconds, paid back many times over when it finds one).
_SHARED_MIN = 4096


class PiecewisePolynomial:
    """A joint-space trajectory made of polynomial segments of degree <= 5.

    Parameters
    ----------
    breaks : array_like, shape (m + 1,)
        Strictly increasing segment boundaries, s. ``breaks[0]`` is usually 0.
    coeffs : array_like, shape (m, d + 1, n_joints)
        Power-basis coefficients in each segment's local time, lowest order
        first; ``d <= 5``.

    Notes
    -----
    Objects are immutable: the arrays are stored read-only. Sampling before
    the start holds the first point and after the end holds the last point at
    rest, the way a controller holds its goal.
    """

    __slots__ = ('_breaks', '_coeffs', '_end_state', '_break_list', '_rows', '_zeros', '_shared')

    def __init__(self, breaks, coeffs):
        breaks = np.array(breaks, dtype=float)
        coeffs = np.array(coeffs, dtype=float, order='C')
        if breaks.ndim != 1 or breaks.size < 2:
            raise ValueError('breaks must be a 1-D array with at least two times')
        if coeffs.ndim != 3 or coeffs.shape[0] != breaks.size - 1:
            raise ValueError(
                f'coeffs must have shape (segments={breaks.size - 1}, degree+1, n_joints); '
                f'got {coeffs.shape}')
        if not 1 <= coeffs.shape[1] <= _N_COEFFS or coeffs.shape[2] < 1:
            raise ValueError(f'polynomial degree must be 0..{MAX_DEGREE} and n_joints >= 1')
        if not (np.isfinite(breaks).all() and np.isfinite(coeffs).all()):
            raise ValueError('breaks and coeffs must be finite')
        if (breaks[1:] <= breaks[:-1]).any():          # np.diff costs several times as much here
            raise ValueError('breaks must be strictly increasing')
        if coeffs.shape[1] == _N_COEFFS:
            padded = coeffs                    # np.array copied it: ours alone
        else:
            padded = np.zeros((coeffs.shape[0], _N_COEFFS, coeffs.shape[2]))
            padded[:, :coeffs.shape[1], :] = coeffs
        breaks.flags.writeable = False
        padded.flags.writeable = False
        self._breaks = breaks
        self._coeffs = padded
        self._end_state = None
        # Built on first use (see _derivative_rows): planning composes many trajectories
        # (stretched, concatenated) that are never sampled themselves.
        self._break_list = None
        self._rows = None
        # A one-segment trajectory's profile its joints share (see _shared_profile): None until
        # asked for (or set by the move that built it), False where they share none.
        self._shared = None
        self._zeros = _rest(coeffs.shape[2])

    # -- shape and time -------------------------------------------------
    @property
    def breaks(self) -> np.ndarray:
        """Segment boundaries, s (read-only)."""
        return self._breaks

    @property
    def coeffs(self) -> np.ndarray:
        """Coefficients, shape (segments, 6, n_joints), lowest order first."""
        return self._coeffs

    @property
    def n_joints(self) -> int:
        return self._coeffs.shape[2]

    @property
    def start_time(self) -> float:
        return float(self._breaks[0])

    @property
    def end_time(self) -> float:
        return float(self._breaks[-1])

    @property
    def duration(self) -> float:
        """Length of the trajectory, s."""
        return float(self._breaks[-1] - self._breaks[0])

    def __repr__(self) -> str:
        return (f'{type(self).__name__}(duration={self.duration:.6g} s, '
                f'segments={len(self._breaks) - 1}, n_joints={self.n_joints})')

    # -- sampling ---------------------------------------------------------
    def sample(self, t):
        """Position, velocity and acceleration at time(s) ``t``.

        Parameters
        ----------
        t : float or array_like, shape (N,)
            Times, s, on the trajectory's own clock (``breaks[0]`` is its start).
            Times outside the trajectory hold its end points at rest.

        Returns
        -------
        q, qd, qdd : ndarray, each shape (N, n_joints)
            Position, velocity (per s) and acceleration (per s^2).

        Notes
        -----
        Vectorised per segment, not per sample: the samples of each segment
        are matrix products of their power basis with the segment's stacked
        (q, qd, qdd) coefficients, a cache-sized chunk at a time. Sorted times
        are the fast path. Where thousands of samples fall in a segment whose
        joints share one profile (a synchronised point-to-point move), that
        profile is evaluated once and scaled per joint.
        """
        if len(self._breaks) == 2 and (done := self._sample_synchronised(t)) is not None:
            return done
        t, t_min, t_max = time_array_and_extremes(t)
        breaks = self._breaks
        n = self.n_joints
        rows = np.empty((3 * n, t.size))
        m = len(breaks) - 1
        outside_any = t_min < breaks[0] or t_max > breaks[-1]
        if _kernels is not None and t.size <= (_GATHER_SAMPLES if m > 1 else _SHARED_MIN):
            _kernels.sample_pieces(breaks, self._coeffs, np.ascontiguousarray(t), rows)
            outside_any = False                            # the kernel held them at rest
        elif m == 1:
            shared = self._one_profile() if t.size >= _SHARED_MIN else None
            _eval_block(t, breaks[0], breaks[-1], breaks[0], None if shared else self._derivative_rows()[0], rows,
                        outside_any, shared)
        elif m > _GATHER_SEGMENTS and t.size <= _GATHER_SAMPLES:
            rows = self._sample_gathered(t)
        else:
            rows = self._sample_by_segment(t, rows, outside_any)
        out = rows.T
        q, qd, qdd = out[:, :n], out[:, n:2 * n], out[:, 2 * n:]
        if outside_any:
            outside = (t < breaks[0]) | (t > breaks[-1])
            qd[outside] = 0.0
            qdd[outside] = 0.0
        return q, qd, qdd

    def _sample_gathered(self, t):
        """The (3n, N) rows at ``t`` for many short segments (a spline through closely spaced samples): one gather and
        one batched product instead of a Python loop over the segments."""
        breaks = self._breaks
        tc = np.clip(t, breaks[0], breaks[-1])
        k = np.clip(np.searchsorted(breaks, tc, side='left') - 1, 0, len(breaks) - 2)
        tau = tc - breaks[k]
        powers = np.empty((tc.size, _N_COEFFS))
        powers[:, 0] = 1.0
        for i in range(1, _N_COEFFS):
            np.multiply(powers[:, i - 1], tau, out=powers[:, i])
        return np.matmul(self._derivative_rows()[k], powers[:, :, None])[:, :, 0].T

    def _sample_by_segment(self, t, rows, outside_any):
        """``rows`` (3n, N) filled at ``t`` a segment at a time, over the times sorted (then put back in order)."""
        breaks = self._breaks
        order, ts = None, t
        if t.size > 1 and (t[1:] < t[:-1]).any():
            order = np.argsort(t, kind='stable')
            ts = t[order]
        # Times before the start fall in the first segment, after the end in the last
        # (each block clips them to the trajectory's ends).
        edges = np.concatenate(([0], np.searchsorted(ts, breaks[1:-1], side='right'), [ts.size]))
        stacked = self._derivative_rows()
        for k in np.flatnonzero(edges[1:] > edges[:-1]):
            lo, hi = edges[k], edges[k + 1]
            _eval_block(ts[lo:hi], breaks[0], breaks[-1], breaks[k], stacked[k], rows, outside_any,
                        _shared_profile(self._coeffs[k]) if hi - lo >= _SHARED_MIN else None, col=lo)
        if order is None:
            return rows
        unsorted = np.empty_like(rows)
        unsorted[:, order] = rows
        return unsorted

    def jerk(self, t):
        """Third derivative at times ``t``, shape (N, n_joints) (zero outside the trajectory).

        At a break, the segment that ends there (as in :meth:`sample`).
        """
        t = as_time_array(t)
        b = self._breaks
        k = np.clip(np.searchsorted(b, t, side='left') - 1, 0, len(b) - 2)
        tau = (t - b[k])[:, None]
        c = self._coeffs[k]                                       # (N, 6, n)
        out = 6.0 * c[:, 3] + 24.0 * c[:, 4] * tau + 60.0 * c[:, 5] * tau * tau
        out[(t < b[0]) | (t > b[-1])] = 0.0
        return out

    def state_at(self, t):
        """``(q, qd, qdd)`` at one time ``t`` (a float), each shape (n_joints,).

        The same values as ``sample(t)`` at a fraction of its cost: what a
        controller calls at every tick (a bisection and one small product).
        Arrays held after the end are shared and read-only.
        """
        b = self._break_list or self._breaks_as_list()
        n = self._coeffs.shape[2]
        if not t <= b[-1]:                       # after the end (NaN too): hold the end, at rest
            return self._end()[0], self._zeros, self._zeros
        if not t > b[0]:
            if t < b[0]:                         # before the start: hold the first point, at rest
                return self._coeffs[0, 0].copy(), np.zeros(n), np.zeros(n)
            return self.start_state()
        k = bisect_left(b, t) - 1                # segment k covers (b[k], b[k+1]], as in sample()
        rows = self._rows if self._rows is not None else self._derivative_rows()
        return self._state_in(rows[k], t - b[k])

    def _state_in(self, rows, tau):
        """``(q, qd, qdd)`` at local time ``tau`` of the segment whose stacked coefficients are
        ``rows`` (3n, 6): one small product."""
        n = self._coeffs.shape[2]
        tau2 = tau * tau
        rows = rows @ np.array((1.0, tau, tau2, tau2 * tau, tau2 * tau2, tau2 * tau2 * tau))
        return rows[:n], rows[n:2 * n], rows[2 * n:]

    def start_state(self):
        """``(q, qd, qdd)`` at the start, each shape (n_joints,)."""
        c = self._coeffs[0]
        return c[0].copy(), c[1].copy(), 2.0 * c[2]

    def end_state(self):
        """``(q, qd, qdd)`` at the end, each shape (n_joints,)."""
        q, qd, qdd = self._end().copy()
        return q, qd, qdd

    def _end(self):
        """The end state, rows q, qd and qdd (3, n_joints), read-only (computed on first use)."""
        if self._end_state is None:
            # The last segment at its end: one small product with the powers of its length and
            # their derivatives (every join and every path asks; no derivative table is built for it).
            tau = float(self._breaks[-1] - self._breaks[-2])
            tau2 = tau * tau
            tau3, tau4 = tau2 * tau, tau2 * tau2
            basis = np.array(((1.0, tau, tau2, tau3, tau4, tau4 * tau),
                              (0.0, 1.0, 2.0 * tau, 3.0 * tau2, 4.0 * tau3, 5.0 * tau4),
                              (0.0, 0.0, 2.0, 6.0 * tau, 12.0 * tau2, 20.0 * tau3)))
            state = basis @ self._coeffs[-1]
            state.flags.writeable = False
            self._end_state = state
        return self._end_state

    def _sample_synchronised(self, t):
        """:meth:`sample` of this one-segment trajectory at thousands of times where its joints
        share a profile, in the compiled pass that also checks the times (two passes over them
        fewer than :func:`time_array_and_extremes`); None where that does not apply."""
        if not (isinstance(t, np.ndarray) and t.ndim == 1 and t.dtype == float and t.size >= _SHARED_MIN):
            return None
        shared = self._one_profile()
        kernel = _compiled_sampler() if shared is not None else None
        if kernel is None:
            return None
        lo, hi = self._breaks.tolist()
        n = self.n_joints
        rows = np.empty((3 * n, t.size))
        out = rows.T
        q, qd, qdd = out[:, :n], out[:, n:2 * n], out[:, 2 * n:]
        if kernel(np.ascontiguousarray(t), lo, hi, lo, *shared, rows, 0):     # a time outside, or NaN
            if not np.isfinite(t).all():
                raise ValueError('t must be finite')
            outside = (t < lo) | (t > hi)
            qd[outside] = 0.0
            qdd[outside] = 0.0
        return q, qd, qdd

    def _one_profile(self):
        """The profile the joints of this one-segment trajectory share (see :func:`_shared_profile`),
        or None (found on first use)."""
        if self._shared is None:
            self._shared = _shared_profile(self._coeffs[0]) or False
        return self._shared or None

    def _derivative_rows(self):
        """Each segment's coefficients of q, qd and qdd, shape (m, 3n, 6), read-only (built on
        first use)."""
        if self._rows is None:
            rows = _stack_derivatives(self._coeffs)
            rows.flags.writeable = False
            self._rows = rows
        return self._rows

    def _breaks_as_list(self):
        """The breaks as a list of floats, for bisection (built on first use)."""
        self._break_list = self._breaks.tolist()
        return self._break_list

    # -- composition ------------------------------------------------------
    def shifted(self, dt: float) -> 'PiecewisePolynomial':
        """The same trajectory starting ``dt`` seconds later."""
        return PiecewisePolynomial(self._breaks + float(dt), self._coeffs)

    def stretched(self, factor: float) -> 'PiecewisePolynomial':
        """The same path taking ``factor`` times as long (from the same start time): velocities
        divided by ``factor``, accelerations by its square, jerks by its cube."""
        factor = float(factor)
        if not (np.isfinite(factor) and factor > 0):
            raise ValueError(f'the stretch factor must be finite and > 0, got {factor}')
        t0 = self._breaks[0]
        powers = factor ** -np.arange(_N_COEFFS, dtype=float)
        return PiecewisePolynomial(t0 + (self._breaks - t0) * factor, self._coeffs * powers[None, :, None])

    def then(self, other: 'PiecewisePolynomial') -> 'PiecewisePolynomial':
        """This trajectory followed by ``other`` (see :func:`concatenate`)."""
        return concatenate([self, other])

    def segment_end_times(self) -> np.ndarray:
        """The times at which segments end, s (for plotting and reports)."""
        return self._breaks[1:].copy()


@functools.lru_cache(maxsize=None)
def _rest(n):
    """Zeros for ``n`` joints, read-only (the velocity and acceleration held after the end)."""
    zeros = np.zeros(n)
    zeros.flags.writeable = False
    return zeros


def _stack_derivatives(coeffs):
    """(m, 6, n) position coefficients -> (m, 3n, 6): the rows of q, qd and qdd, one per joint each."""
    m, _, n = coeffs.shape
    out = np.zeros((m, 3 * n, _N_COEFFS))
    c = coeffs.transpose(0, 2, 1)
    out[:, :n] = c
    np.multiply(c[:, :, 1:], _D1, out=out[:, n:2 * n, :-1])
    np.multiply(c[:, :, 2:], _D2, out=out[:, 2 * n:, :-2])
    return out


def _eval_block(t, lo, hi, origin, rows, out, clip=True, shared=None, col=0):
    """Write q, qd, qdd at times ``t`` (clipped to ``[lo, hi]``, local to ``origin``) into
    ``out[:, col:col + len(t)]`` (3n rows), from one segment's ``rows`` (3n, 6) of stacked
    coefficients.
    ``clip=False`` when no time lies outside ``[lo, hi]``: numpy skips the clip (a quarter of
    the power basis's cost; the compiled sampler clips every time, at no cost it can measure).

    A chunk at a time: each chunk's power basis stays in cache and no full-length
    temporary is written, so a long sampling costs little more than writing its output.
    Given a profile the segment's joints share (``shared``, see :func:`_shared_profile`;
    ``rows`` is not needed then), it is evaluated once and scaled per joint: by the compiled
    :func:`.fast_sample.sample_shared` in one pass, or (without numba) by numpy with a third
    of the products.
    """
    size = t.size
    if shared is not None and (kernel := _compiled_sampler()) is not None:
        kernel(np.ascontiguousarray(t), lo, hi, origin, *shared, out, col)
        return
    out = out[:, col:col + size]
    basis, dst = (rows, out) if shared is None else (shared[0], np.empty((3, size)))
    powers = np.empty((_N_COEFFS, min(size, _CHUNK)))
    powers[0] = 1.0
    for a in range(0, size, _CHUNK):
        b = min(a + _CHUNK, size)
        p = powers[:, :b - a]
        tau = p[1]
        if clip:
            np.clip(t[a:b], lo, hi, out=tau)
            tau -= origin
        else:
            np.subtract(t[a:b], origin, out=tau)
        for i in range(2, _N_COEFFS):
            np.multiply(p[i - 1], tau, out=p[i])
        np.matmul(basis, p, out=dst[:, a:b])
    if shared is not None:
        _, w, c0 = shared
        n = w.size
        for i in range(3):
            np.multiply(w[:, None], dst[i], out=out[i * n:(i + 1) * n])
        out[:n] += c0[:, None]


def _shared_profile(coeffs):
    """``(U, w, c0)`` when every joint of a segment moves along one polynomial ``s``, scaled:
    ``q_j(tau) = c0_j + w_j s(tau)`` (a synchronised point-to-point move, such as a cubic or
    quintic from rest to rest); None otherwise. ``U`` (3, 6) maps the power basis to s and its
    first two derivatives.
    """
    rest = coeffs[1:]                                      # (5, n): the part that moves
    size = np.abs(rest)
    v = rest[:, int(size.max(axis=0).argmax())]            # the joint that moves most: s itself
    vv = float(v @ v)
    w = (v @ rest) / vv if vv > 0.0 else np.zeros(rest.shape[1])
    # Each power on its own scale (a short move's tau^5 coefficient dwarfs its velocity's).
    if vv > 0.0 and (np.abs(rest - np.outer(v, w)) > 1e-12 * size.max(axis=1, keepdims=True)).any():
        return None
    s = np.concatenate(([0.0], v))                         # the profile, from 0 at tau = 0
    return _stack_derivatives(s[None, :, None])[0], w, coeffs[0]


#: The compiled trajectory kernels (:mod:`.fast_sample`), once a process asked for them with
#: :func:`use_compiled_kernels`; None: numpy samples many segments and builds splines.
_kernels = None
_kernels_tried = False


def use_compiled_kernels():
    """From now on, in this process, use the compiled kernels of :mod:`.fast_sample`: sample
    trajectories (of many segments at up to ``_GATHER_SAMPLES`` times at once, of one at fewer
    than ``_SHARED_MIN``), build the spline through a path's samples (:func:`.quintic_via`),
    merge joints' pieces and check joint limits. True if they loaded (numba installed and able
    to compile or cache them here), else numpy goes on doing all of it.

    A planner asks for them when it starts: every line's spline is built once and sampled and
    checked several times while it is planned (together about a third of a pick cycle's
    planning with numpy). A controller does not: its first trajectory would stall its loop for
    numba's import.
    """
    global _kernels, _kernels_tried
    if not _kernels_tried:
        _kernels_tried = True
        _kernels = load(f'{__package__}.fast_sample', 'the compiled trajectory kernels',
                        'numpy samples and builds the splines')
    return _kernels is not None


def compiled_kernels():
    """:mod:`.fast_sample` once this process asked for it (:func:`use_compiled_kernels`), else None."""
    return _kernels


@functools.cache
def _compiled_sampler():
    """:func:`.fast_sample.sample_shared`, loaded on the first long sampling of a synchronised
    segment; None without numba, or (with a warning) if numba cannot compile or cache it here."""
    fast_sample = load(f'{__package__}.fast_sample', 'the compiled sampler', 'long samplings run with numpy')
    return None if fast_sample is None else fast_sample.sample_shared


def taylor_shift(coeffs, dt):
    """Re-expand power-basis polynomials about a later origin.

    Parameters
    ----------
    coeffs : ndarray, shape (K, 6, n)
        Polynomials in local time ``tau``.
    dt : ndarray, shape (K,) or (K, n)
        New origin ``tau = dt`` for each polynomial (per joint if 2-D).

    Returns
    -------
    ndarray, shape (K, 6, n)
        Coefficients ``c'`` with ``p(tau) = sum c'_i (tau - dt)^i``.
    """
    dt = np.asarray(dt, dtype=float)
    if dt.ndim == 1:
        dt = dt[:, None]
    # Repeated synthetic division (Horner's scheme): 15 fused steps instead of the
    # binomial sum's 21 terms of powers and products for a quintic, 3 for the parabolas of
    # LSPB phases (zero leading coefficients stay zero and are skipped).
    # (Coefficient-major, so that every step runs over contiguous memory.)
    c = np.array(np.moveaxis(np.asarray(coeffs, dtype=float), 1, 0), order='C')
    step = np.empty(np.broadcast_shapes(c[0].shape, dt.shape))
    degree = c.shape[0] - 1
    while degree > 0 and not c[degree].any():
        degree -= 1
    for i in range(degree):
        for j in range(degree - 1, i - 1, -1):
            np.multiply(c[j + 1], dt, out=step)
            c[j] += step
    return np.moveaxis(c, 0, 1)


def merge_joint_pieces(joint_breaks, joint_coeffs, rtol=1e-12):
    """Combine per-joint piecewise polynomials with different breaks into one.

    Parameters
    ----------
    joint_breaks : ndarray, shape (P + 1, n)
        Non-decreasing boundaries of each joint's P pieces (zero-width pieces
        are allowed and ignored).
    joint_coeffs : ndarray, shape (P, 6, n)
        Each joint's piece polynomials in the piece's local time.

    Returns
    -------
    breaks : ndarray, shape (K + 1,)
        The union of all joints' boundaries.
    coeffs : ndarray, shape (K, 6, n)
        Every joint's polynomial on each interval of the union (for
        :class:`PiecewisePolynomial`).
    """
    joint_breaks = np.asarray(joint_breaks, dtype=float)
    n_pieces, _, n = joint_coeffs.shape
    union = np.unique(joint_breaks)
    span = union[-1] - union[0]
    # Fold boundaries that differ only by rounding into one.
    keep = np.concatenate(([True], np.diff(union) > rtol * max(span, 1.0)))
    union = union[keep]
    union[-1] = joint_breaks[-1].max()
    if _kernels is not None and joint_coeffs.shape[1] == _N_COEFFS:
        shifted = np.empty((union.size - 1, _N_COEFFS, n))
        _kernels.merge_pieces(np.ascontiguousarray(joint_breaks), np.ascontiguousarray(joint_coeffs, dtype=float),
                              union, shifted)
        return union, shifted
    starts = union[:-1]
    mids = 0.5 * (union[:-1] + union[1:])
    # Piece index of each joint at each interval midpoint, vectorised over joints.
    piece = (mids[:, None, None] >= joint_breaks[None, 1:-1, :]).sum(axis=1)  # (K, n)
    np.clip(piece, 0, n_pieces - 1, out=piece)
    cols = np.arange(n)[None, :]
    local = joint_coeffs.transpose(0, 2, 1)[piece, cols]          # (K, n, 6)
    dt = starts[:, None] - joint_breaks[piece, cols]              # (K, n)
    shifted = taylor_shift(local.transpose(0, 2, 1), dt)          # (K, 6, n)
    return union, shifted


def concatenate(trajectories):
    """Join trajectories end to start into one.

    Each trajectory is shifted in time to start where the previous one ends.
    Positions and velocities must meet at the joins (within 1e-9 relative); a
    :class:`ValueError` names the first join that does not. Accelerations may
    step, as they do inside cubic and LSPB moves.

    Parameters
    ----------
    trajectories : sequence of PiecewisePolynomial
        At least one, all with the same number of joints.

    Returns
    -------
    PiecewisePolynomial
    """
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError('concatenate needs at least one trajectory')
    n = trajectories[0].n_joints
    for i, nxt in enumerate(trajectories[1:], start=1):
        if nxt.n_joints != n:
            raise ValueError(f'trajectory {i} has {nxt.n_joints} joints, the first has {n}')
    if len(trajectories) > 1:
        # Every join at once: (joins, position/velocity, joints) at each side.
        ends = np.array([tr._end()[:2] for tr in trajectories[:-1]])
        starts = np.array([tr.coeffs[0, :2] for tr in trajectories[1:]])
        scale = np.maximum(1.0, np.maximum(np.abs(ends).max(axis=2), np.abs(starts).max(axis=2)))
        bad = np.abs(ends - starts).max(axis=2) > 1e-9 * scale
        if bad.any():
            i, which = (int(x) for x in np.argwhere(bad)[0])
            raise ValueError(
                f'trajectory {i + 1} does not start where trajectory {i} ends: '
                f'{("position", "velocity")[which]} {np.round(starts[i, which], 9).tolist()} != '
                f'{np.round(ends[i, which], 9).tolist()}')
    breaks = [trajectories[0].breaks - trajectories[0].start_time]
    t_end = breaks[0][-1]
    for nxt in trajectories[1:]:
        breaks.append(nxt.breaks[1:] - nxt.start_time + t_end)
        t_end = breaks[-1][-1]
    return PiecewisePolynomial(np.concatenate(breaks), np.concatenate([tr.coeffs for tr in trajectories]))


def stack(trajectories):
    """Put trajectories of the same time span side by side as more joints.

    Parameters
    ----------
    trajectories : sequence of PiecewisePolynomial
        Same start and end time (within 1e-9 s).

    Returns
    -------
    PiecewisePolynomial
        Breaks at the union of theirs; joints in the order given.
    """
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError('stack needs at least one trajectory')
    t0, t1 = trajectories[0].start_time, trajectories[0].end_time
    for i, tr in enumerate(trajectories[1:], start=1):
        if abs(tr.start_time - t0) > 1e-9 or abs(tr.end_time - t1) > 1e-9:
            raise ValueError(f'trajectory {i} spans [{tr.start_time:.6g}, {tr.end_time:.6g}] s, '
                             f'the first [{t0:.6g}, {t1:.6g}] s')
    union = np.unique(np.concatenate([tr.breaks for tr in trajectories]))
    keep = np.concatenate(([True], np.diff(union) > 1e-12 * max(1.0, t1 - t0)))
    union = union[keep]
    union[0], union[-1] = t0, t1
    starts, mids = union[:-1], 0.5 * (union[:-1] + union[1:])
    blocks = []
    for tr in trajectories:
        seg = np.clip(np.searchsorted(tr.breaks, mids, side='right') - 1, 0, len(tr.breaks) - 2)
        coeffs, shift = tr.coeffs[seg], starts - tr.breaks[seg]
        # The intervals that start inside one of its segments, and not constant there (a
        # gripper holding its opening through the arm's many segments needs no shift).
        moved = (shift != 0.0) & coeffs[:, 1:].any(axis=(1, 2))
        if moved.any():
            coeffs[moved] = taylor_shift(coeffs[moved], shift[moved])
        blocks.append(coeffs)
    return PiecewisePolynomial(union, np.concatenate(blocks, axis=2))


def hold(q, duration):
    """Stand still at ``q`` for ``duration`` seconds (a dwell, e.g. a grasp).

    Parameters
    ----------
    q : float or array_like, shape (n_joints,)
    duration : float
        Seconds, > 0.
    """
    q = as_joint_vector(q, 'q')
    duration = as_duration(duration)
    coeffs = np.zeros((1, 1, q.size))
    coeffs[0, 0] = q
    return PiecewisePolynomial([0.0, duration], coeffs)
