"""Property tests: boundary conditions, continuity, symmetry and refusals over random inputs."""

import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from picking_core import trajectory

angle = st.floats(-180.0, 180.0, allow_nan=False)
duration = st.floats(0.05, 20.0, allow_nan=False)
joints = st.integers(1, 6)


def vectors(n):
    return st.lists(angle, min_size=n, max_size=n).map(np.array)


@st.composite
def moves(draw):
    n = draw(joints)
    return draw(vectors(n)), draw(vectors(n)), draw(duration)


def _continuous(traj, tol=1e-6):
    """Position and velocity have no jump at any break."""
    inner = traj.breaks[1:-1]
    if inner.size == 0:
        return
    eps = 1e-9 * max(1.0, traj.duration)
    left = traj.sample(inner - eps)
    right = traj.sample(inner + eps)
    scale = max(1.0, float(np.abs(left[1]).max()))
    assert np.abs(left[0] - right[0]).max() <= tol * scale
    assert np.abs(left[1] - right[1]).max() <= tol * scale * 1e3 * max(1.0, 1.0 / traj.duration)


@given(moves())
def test_cubic_and_quintic_meet_their_end_conditions(move):
    q0, qf, tf = move
    for seg in (trajectory.cubic(q0, qf, tf), trajectory.quintic(q0, qf, tf)):
        q, qd, qdd = seg.sample([0.0, tf])
        assert q == pytest.approx(np.stack([q0, qf]), abs=1e-9 * (1 + np.abs(qf).max()))
        assert qd == pytest.approx(np.zeros_like(qd), abs=1e-8 * (1 + np.abs(qf - q0).max()) / tf)
    qdd = trajectory.quintic(q0, qf, tf).sample([0.0, tf])[2]
    assert np.abs(qdd).max() <= 1e-7 * (1 + np.abs(qf - q0).max()) / tf**2


@given(moves(), st.floats(1.0, 3.0))
def test_lspb_peak_acceleration_symmetry_and_monotonicity(move, factor):
    q0, qf, tf = move
    amin = trajectory.min_lspb_accel(q0, qf, tf)
    accel = np.maximum(amin * factor, 1e-3)
    seg = trajectory.lspb(q0, qf, tf, accel)
    t = np.linspace(0.0, tf, 401)
    q, qd, qdd = seg.sample(t)
    # Boundary conditions.
    assert q[0] == pytest.approx(q0, abs=1e-9 * (1 + np.abs(q0).max()))
    assert q[-1] == pytest.approx(qf, abs=1e-7 * (1 + np.abs(qf).max()))
    # Peak |qdd| is the given acceleration (for joints that move).
    moving = np.abs(qf - q0) > 1e-6
    assert np.all(np.abs(qdd) <= accel * (1 + 1e-9) + 1e-12)
    if moving.any():
        assert np.abs(qdd).max(axis=0)[moving] == pytest.approx(accel[moving])
    # Fig. 8: symmetric about (tf/2, (q0 + qf)/2).
    qr, qdr, _ = seg.sample(tf - t)
    mid = 0.5 * (q0 + qf)
    assert q - mid == pytest.approx(-(qr - mid), abs=1e-6 * (1 + np.abs(q).max()))
    assert qd == pytest.approx(qdr, abs=1e-6 * (1 + np.abs(qd).max()))
    # A monotonic move stays monotonic.
    steps = np.diff(q, axis=0) * np.sign(qf - q0)
    assert steps.min() >= -1e-9 * (1 + np.abs(q).max())
    _continuous(seg)


@given(moves(), st.floats(0.01, 0.99))
def test_lspb_below_eq20_minimum_is_a_value_error(move, fraction):
    q0, qf, tf = move
    amin = trajectory.min_lspb_accel(q0, qf, tf)
    assume(amin.max() > 1e-6)
    with pytest.raises(ValueError, match='Eq. 20'):
        trajectory.lspb(q0, qf, tf, amin.max() * fraction)


@st.composite
def via_paths(draw):
    n = draw(joints)
    m = draw(st.integers(1, 6))
    points = np.array([draw(vectors(n)) for _ in range(m + 1)])
    durations = np.array(draw(st.lists(st.floats(0.2, 5.0), min_size=m, max_size=m)))
    return points, durations


@given(via_paths())
@settings(deadline=None)
def test_via_lspb_ends_exact_at_rest_and_continuous(path):
    points, durations = path
    # An acceleration large enough for every segment: 8 * max step / shortest duration^2.
    accel = 8.0 * (np.abs(np.diff(points, axis=0)).max() + 1.0) / durations.min() ** 2
    traj = trajectory.via_lspb(points, durations, accel)
    assert traj.duration == pytest.approx(durations.sum())
    q, qd, qdd = traj.sample([0.0, traj.duration])
    scale = 1 + np.abs(points).max()
    assert q == pytest.approx(points[[0, -1]], abs=1e-7 * scale)
    assert np.abs(qd).max() <= 1e-6 * scale
    t = np.linspace(0, traj.duration, 1000)
    assert np.abs(traj.sample(t)[2]).max() <= accel * (1 + 1e-9)
    _continuous(traj)


@given(via_paths())
@settings(deadline=None)
def test_quintic_via_passes_every_point_with_continuous_velocity_and_acceleration(path):
    points, durations = path
    traj = trajectory.quintic_via(points, durations)
    times = np.concatenate(([0.0], np.cumsum(durations)))
    q, qd, qdd = traj.sample(times)
    scale = 1 + np.abs(points).max()
    assert q == pytest.approx(points, abs=1e-7 * scale)
    assert np.abs(qd[[0, -1]]).max() <= 1e-6 * scale
    inner = times[1:-1]
    if inner.size:
        left, right = traj.sample(inner - 1e-9), traj.sample(inner + 1e-9)
        for a, b in zip(left, right):
            assert np.abs(a - b).max() <= 1e-4 * scale * (1 + 1 / durations.min() ** 3)


@given(via_paths(), st.booleans(), st.booleans())
@settings(deadline=None)
def test_quintic_via_takes_the_cubic_splines_velocities_and_accelerations(path, free_start, free_end):
    """The knot velocities and accelerations come from our own tridiagonal solve: scipy's
    CubicSpline through the same points, with the same ends (at rest: clamped; free:
    not-a-knot), gives the same (an end at rest has acceleration 0)."""
    from scipy.interpolate import CubicSpline
    points, durations = path
    times = np.concatenate(([0.0], np.cumsum(durations)))
    free = tuple(f and len(durations) > 1 for f in (free_start, free_end))   # as quintic_via takes them
    rest = (1, np.zeros(points.shape[1]))
    spline = CubicSpline(times, points, bc_type=tuple('not-a-knot' if f else rest for f in free), axis=0)
    _, qd, qdd = trajectory.quintic_via(points, durations, free_ends=(free_start, free_end)).sample(times)
    vel, acc = spline(times, 1), spline(times, 2)
    for end, f in zip((0, -1), free):
        if not f:
            acc[end] = 0.0
    for ours, scipys in ((qd, vel), (qdd, acc)):
        assert ours == pytest.approx(scipys, rel=1e-6, abs=1e-9 * (1 + np.abs(scipys).max()))


BAD_NUMBERS = st.sampled_from([float('nan'), float('inf'), -float('inf')])


@given(BAD_NUMBERS, st.sampled_from(['q0', 'qf', 'duration', 'accel']))
def test_non_finite_input_is_a_value_error(bad, which):
    args = dict(q0=0.0, qf=1.0, duration=1.0, accel=10.0)
    args[which] = bad
    with pytest.raises(ValueError):
        trajectory.lspb(**args)
    if which != 'accel':
        args.pop('accel')
        with pytest.raises(ValueError):
            trajectory.cubic(**args)
        with pytest.raises(ValueError):
            trajectory.quintic(**args)


@pytest.mark.parametrize('bad_duration', [0.0, -1.0])
def test_non_positive_duration_is_a_value_error(bad_duration):
    for make in (trajectory.cubic, trajectory.quintic):
        with pytest.raises(ValueError, match='duration'):
            make(0.0, 1.0, bad_duration)


def test_mismatched_joint_counts_are_a_value_error():
    with pytest.raises(ValueError, match='joints'):
        trajectory.cubic([0.0, 1.0], [1.0, 2.0, 3.0], 1.0)
    with pytest.raises(ValueError, match='durations'):
        trajectory.via_lspb([[0.0], [1.0], [2.0]], [1.0], 10.0)


def test_lspb_that_does_not_move_stays_put():
    seg = trajectory.lspb([1.0, 2.0], [1.0, 3.0], 2.0, 5.0)
    q, qd, qdd = seg.sample(np.linspace(0, 2, 11))
    assert np.all(q[:, 0] == 1.0) and np.all(qd[:, 0] == 0.0) and np.all(qdd[:, 0] == 0.0)


def test_sample_shapes_and_holding_outside_the_trajectory():
    seg = trajectory.cubic([0.0, 1.0, 2.0], [1.0, 2.0, 3.0], 2.0)
    q, qd, qdd = seg.sample(np.linspace(-1.0, 3.0, 9))
    assert q.shape == qd.shape == qdd.shape == (9, 3)
    assert q[0] == pytest.approx([0.0, 1.0, 2.0]) and q[-1] == pytest.approx([1.0, 2.0, 3.0])
    assert np.all(qd[[0, -1]] == 0.0)
    assert seg.sample(0.5)[0].shape == (1, 3)
    assert seg.sample([])[0].shape == (0, 3)


@pytest.mark.parametrize('bad', [np.nan, np.inf, -np.inf])
def test_non_finite_sample_times_are_a_value_error(bad):
    seg = trajectory.quintic([0.0, 1.0], [1.0, 2.0], 2.0)
    with pytest.raises(ValueError, match='t must be finite'):
        seg.sample([0.0, bad, 1.0])



@pytest.mark.parametrize('make', [
    lambda: trajectory.quintic([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0).shifted(0.3),      # one segment
    lambda: trajectory.quintic([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0, [0.5, 0.0, -1.0]),  # no shared profile
    lambda: trajectory.hold([0.3, -1.0, 2.0], 1.5),                                        # no motion
    lambda: trajectory.lspb([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0, 6.0),               # a few segments
    lambda: trajectory.quintic_via(np.sin(np.arange(40.0))[:, None] * [1.0, 2.0, -1.0],  # many: gathered
                                   np.full(39, 0.05)),
])
@pytest.mark.parametrize('n', [5, 20_001, 40_000])
@pytest.mark.parametrize('beyond', [0.5, 0.0])
@pytest.mark.parametrize('in_order', [False, True])
def test_long_samplings_match_one_time_at_a_time(make, n, beyond, in_order):
    """Many cache-sized chunks, times in or out of order, beyond both ends or all within
    (then nothing is clipped): each sample is exactly what the trajectory gives at that time."""
    traj = make()
    rng = np.random.default_rng(n)
    t = rng.uniform(traj.start_time - beyond, traj.end_time + beyond, n)
    t[:3] = traj.start_time - 2 * beyond, traj.end_time + 2 * beyond, traj.breaks[len(traj.breaks) // 2]
    if in_order:
        t.sort()
    q, qd, qdd = traj.sample(t)
    for i in rng.choice(n, 200 if n > 200 else n, replace=False).tolist() + [0, 1, 2, n - 1]:
        want = traj.state_at(float(t[i]))
        for got, w in zip((q[i], qd[i], qdd[i]), want):
            assert got == pytest.approx(w, rel=1e-12, abs=1e-9)
    assert np.all(qd[t > traj.end_time] == 0.0) and np.all(qdd[t < traj.start_time] == 0.0)


def test_a_profile_the_joints_share_is_found_only_where_there_is_one():
    """Long samplings of a synchronised move evaluate one profile and scale it per joint;
    a move whose joints do not all follow one profile is never taken for one."""
    from picking_core.trajectory.piecewise import _shared_profile
    q0, qf = [0.0, 1.0, -2.0], [1.0, -2.0, 0.5]
    for traj in (trajectory.quintic(q0, qf, 2.0), trajectory.cubic(q0, qf, 2.0), trajectory.hold(q0, 1.0),
                 trajectory.quintic([0.5], [2.0], 1.0)):
        U, w, c0 = _shared_profile(traj.coeffs[0])
        tau = np.array([0.0, 0.3, 0.7])
        powers = tau[None, :] ** np.arange(6)[:, None]
        q, qd, qdd = traj.sample(tau)
        s = U @ powers
        for i, want in enumerate((q - c0, qd, qdd)):
            assert np.outer(s[i], w) == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert _shared_profile(trajectory.quintic(q0, qf, 2.0, [0.5, 0.0, -1.0]).coeffs[0]) is None
    assert _shared_profile(trajectory.quintic(q0, qf, 2.0, af=[0.0, 0.0, 1e-6]).coeffs[0]) is None
    # A short move: one joint's velocity term, tiny beside the tau^5 coefficients, is its own.
    coeffs = trajectory.quintic(q0, qf, 0.01).coeffs.copy()
    coeffs[0, 1, 0] += 1e-6
    assert _shared_profile(coeffs[0]) is None


@pytest.mark.parametrize('make', [
    lambda: trajectory.quintic([0.0, 1.0, -2.0, 0.4], [1.0, -2.0, 0.5, 0.4], 2.0).shifted(0.3),
    lambda: trajectory.cubic([0.5], [-1.5], 1.0),
    lambda: trajectory.lspb([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0, 6.0),     # three shared segments
])
@pytest.mark.parametrize('beyond', [0.4, 0.0])
def test_long_samplings_of_a_shared_profile_are_the_same_compiled_or_with_numpy(make, beyond, monkeypatch):
    """The compiled one-pass sampler (numba) and the numpy fallback write the same samples,
    clipped or not, into a segment's part of the output or all of it, in one chunk or several."""
    pytest.importorskip('numba')
    from picking_core.trajectory import fast_sample, piecewise
    traj = make()
    span = (traj.start_time - beyond, traj.end_time + beyond)
    t = np.linspace(*span, 30_001)
    times = (t, t[::-1], np.linspace(*span, 60_002)[::2],                      # strided
             np.linspace(*span, 2 * fast_sample.CHUNK + 7))                     # three chunks
    assert piecewise._compiled_sampler() is not None
    compiled = [traj.sample(x) for x in times]
    monkeypatch.setattr(piecewise, '_compiled_sampler', lambda: None)
    with_numpy = [traj.sample(x) for x in times]
    for one, other in zip(compiled, with_numpy):
        for got, want in zip(one, other):
            np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize('kind', ['cubic', 'quintic'])
def test_a_move_from_rest_to_rest_is_the_general_one_and_knows_its_shared_profile(kind):
    """From rest to rest (the default), a cubic or quintic is built as one profile scaled per
    joint: the general Hermite move's coefficients to rounding, and the profile its joints
    share set at once (a long sampling needs not look for it), the one found by looking."""
    from picking_core.trajectory.piecewise import _shared_profile
    make = getattr(trajectory, kind)
    rng = np.random.default_rng(4)
    for _ in range(20):
        q0, qf, T = rng.uniform(-2.0, 2.0, 5), rng.uniform(-2.0, 2.0, 5), float(rng.uniform(0.01, 5.0))
        rest = make(q0, qf, T)
        general = make(q0, qf, T, v0=np.zeros(5)) if kind == 'cubic' else make(q0, qf, T, a0=np.zeros(5))
        assert rest.coeffs == pytest.approx(general.coeffs, rel=1e-12, abs=1e-12 * np.abs(general.coeffs).max())
        U, w, c0 = rest._one_profile()
        found = _shared_profile(rest.coeffs[0])
        assert np.outer(U[0], w) == pytest.approx(np.outer(found[0][0], found[1]), rel=1e-12, abs=1e-12)
        assert np.array_equal(c0, q0)


def test_a_long_sampling_checks_its_times_in_the_compiled_pass(monkeypatch):
    """The compiled sampler of a synchronised move checks the times as it reads them: a NaN or
    an infinite time among 100 000 is refused as before, and times outside the move hold its
    ends at rest, as numpy has them."""
    pytest.importorskip('numba')
    from picking_core.trajectory import piecewise
    traj = trajectory.quintic([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0)
    for bad in (np.nan, np.inf, -np.inf):
        t = np.linspace(0.0, 2.0, 100_000)
        t[77_777] = bad
        with pytest.raises(ValueError, match='t must be finite'):
            traj.sample(t)
    t = np.linspace(-0.5, 2.5, 100_000)
    compiled = traj.sample(t)
    monkeypatch.setattr(piecewise, '_compiled_sampler', lambda: None)
    with_numpy = traj.sample(t)
    outside = (t < 0.0) | (t > 2.0)
    for got, want in zip(compiled, with_numpy):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-12)
    assert not compiled[1][outside].any() and not compiled[2][outside].any()


@pytest.mark.parametrize('make', [
    lambda: trajectory.quintic([0.0, 1.0, -2.0], [1.0, -2.0, 0.5], 2.0).shifted(0.3),       # one segment
    lambda: trajectory.quintic_via(np.random.default_rng(3).uniform(-1.0, 1.0, (41, 6)), np.full(40, 0.01)),
    lambda: trajectory.via_lspb([[0.0, 1.0], [0.5, -1.0], [2.0, 0.0], [1.0, 1.0]], [1.0, 0.5, 2.0], 40.0),
    lambda: trajectory.concatenate([trajectory.cubic([0.0], [1.0], 1.0), trajectory.hold([1.0], 0.25),
                                    trajectory.quintic([1.0], [-0.5], 0.5)]).shifted(2.0),
])
def test_short_samplings_of_many_segments_are_the_same_compiled_or_with_numpy(make, monkeypatch):
    """The compiled sampler of short samplings (of one segment or many) and numpy give the same
    q, qd and qdd: times in
    order or not, at the breaks (the segment that ends there), before the start and after the
    end (held, at rest)."""
    pytest.importorskip('numba')
    from picking_core.trajectory import piecewise
    traj = make()
    b = traj.breaks
    t = np.linspace(b[0] - 0.3, b[-1] + 0.3, 777)
    times = (t, np.random.default_rng(5).permutation(t), b, b[::-1], np.array([b[-1] + 1.0]))
    assert trajectory.use_compiled_kernels() and piecewise._kernels is not None
    compiled = [traj.sample(x) for x in times]
    monkeypatch.setattr(piecewise, '_kernels', None)
    with_numpy = [traj.sample(x) for x in times]
    for one, other in zip(compiled, with_numpy):
        for got, want in zip(one, other):
            # Horner's scheme against a product with the powers: the same to rounding of the
            # largest term (a spline's accelerations near 1e4, where the true one is 0 at the end).
            np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13 * max(1.0, np.abs(want).max()))
    q, qd, qdd = compiled[0]
    outside = (t < b[0]) | (t > b[-1])
    assert outside.sum() > 100 and not qd[outside].any() and not qdd[outside].any()
    end = traj.end_state()
    np.testing.assert_allclose(q[-1], end[0], atol=1e-12)


@pytest.mark.parametrize('free', [(False, False), (True, False), (False, True), (True, True)])
def test_the_spline_through_samples_is_the_same_compiled_or_with_numpy(free, monkeypatch):
    """quintic_via without velocities (the spline through a path's IK samples): the compiled
    kernel's segments are those of the cubic spline's tridiagonal solve and the Hermite
    quintics with numpy, ends at rest or free, from 2 points (no free end possible) to 60."""
    pytest.importorskip('numba')
    from picking_core.trajectory import piecewise
    assert trajectory.use_compiled_kernels()
    rng = np.random.default_rng(11)
    for m in (1, 2, 3, 4, 7, 59):
        points = rng.uniform(-2.0, 2.0, (m + 1, 6))
        for durations in (np.full(m, 0.01), rng.uniform(0.05, 1.0, m)):
            compiled = trajectory.quintic_via(points, durations, free_ends=free)
            with monkeypatch.context() as patch:
                patch.setattr(piecewise, '_kernels', None)
                with_numpy = trajectory.quintic_via(points, durations, free_ends=free)
            assert np.array_equal(compiled.breaks, with_numpy.breaks)
            t = np.linspace(0.0, compiled.duration, 20 * m + 1)
            for got, want in zip(compiled.sample(t), with_numpy.sample(t)):
                # To rounding: solved another way, the coefficients of high powers (which
                # cancel to ~0 where a free end's two cubics are one) differ in their last digits.
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.abs(want).max())


def test_joint_pieces_merged_compiled_are_those_merged_with_numpy(monkeypatch):
    """LSPB moves, via-point LSPB and jerk-limited moves and stops (each joint's pieces merged over
    the union of their breaks; a jerk-limited move then ends exactly on its target): the compiled
    kernels give numpy's breaks and coefficients bit for bit (the same arithmetic in the same order)."""
    pytest.importorskip('numba')
    from picking_core.trajectory import piecewise
    assert trajectory.use_compiled_kernels()
    rng = np.random.default_rng(8)
    makes = []
    for _ in range(40):
        m, n = int(rng.integers(1, 6)), int(rng.integers(1, 7))
        points, durations = rng.uniform(-1.0, 1.0, (m + 1, n)), rng.uniform(0.4, 1.5, m)
        makes.append(lambda p=points, d=durations: trajectory.via_lspb(p, d, 40.0))
        makes.append(lambda p=points: trajectory.lspb(p[0], p[1], 1.5, 10.0))
        makes.append(lambda p=points: trajectory.time_optimal(p[0], p[1], np.full(p.shape[1], 2.0),
                                                              np.full(p.shape[1], 8.0), np.full(p.shape[1], 80.0)))
        # Moving at the start (a blend), and a stop from a moving state (Ruckig's brake pre-phase where the
        # start is beyond a limit).
        makes.append(lambda p=points: trajectory.time_optimal(p[0], p[1], 2.0, 8.0, 80.0, v0=1.5 * p[1], a0=4.0 * p[0]))
        makes.append(lambda p=points: trajectory.time_optimal_stop(p[0], 3.0 * p[1], 10.0 * p[0], 2.0, 8.0, 80.0))
    compiled = [make() for make in makes]
    monkeypatch.setattr(piecewise, '_kernels', None)
    for make, one in zip(makes, compiled):
        other = make()
        assert np.array_equal(one.breaks, other.breaks) and np.array_equal(one.coeffs, other.coeffs)


def test_via_point_timing_compiled_is_the_numpy_timing_and_refuses_alike(monkeypatch):
    """The blends and line speeds of LSPB through via points, which the planner searches
    durations with: compiled, numpy's bit for bit; where a segment is too short (an end that
    cannot reach its line from rest, or blends longer than a segment), the same refusal,
    naming the same segment and joint. Points, durations and accelerations drawn across the
    border between the two."""
    pytest.importorskip('numba')
    from picking_core.trajectory import piecewise
    assert trajectory.use_compiled_kernels()
    rng = np.random.default_rng(12)
    cases = []
    for _ in range(3000):
        m, n = int(rng.integers(2, 7)), int(rng.integers(1, 7))
        cases.append((rng.uniform(-1.0, 1.0, (m + 1, n)), rng.uniform(0.05, 1.5, m),
                      10.0 ** rng.uniform(-0.5, 2.0, n)))

    def outcomes():
        out = []
        for points, durations, accel in cases:
            try:
                out.append(trajectory.via_lspb_timing(points, durations, accel))
            except ValueError as exc:
                out.append(str(exc))
        return out
    compiled = outcomes()
    monkeypatch.setattr(piecewise, '_kernels', None)
    with_numpy = outcomes()
    kinds = {type(x) for x in compiled}
    assert kinds == {tuple, str}, 'both timings and refusals are drawn'
    ends = sum('segment of joint' in x for x in compiled if isinstance(x, str))
    assert 0 < ends < sum(isinstance(x, str) for x in compiled), 'both kinds of refusal are drawn'
    for one, other in zip(compiled, with_numpy):
        if isinstance(other, str):
            assert one == other
        else:
            assert all(np.array_equal(x, y) for x, y in zip(one, other))


def test_a_compiled_kernel_that_cannot_load_leaves_numpy_to_answer(monkeypatch):
    """Without numba: silently None. numba failing (no writable cache directory, say): None and a
    RuntimeWarning that says what did not load, why, and what answers instead."""
    import warnings

    from picking_core import compiled
    from picking_core.trajectory import piecewise

    def missing(name):
        raise ImportError(f'No module named {name!r}')

    def failing(name):
        raise OSError('no writable cache directory')
    monkeypatch.setattr(compiled.importlib, 'import_module', missing)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert piecewise._compiled_sampler.__wrapped__() is None
    monkeypatch.setattr(compiled.importlib, 'import_module', failing)
    with pytest.warns(RuntimeWarning, match=r'the compiled sampler did not load \(OSError: no writable cache '
                                            r'directory\); long samplings run with numpy'):
        assert piecewise._compiled_sampler.__wrapped__() is None
    monkeypatch.setattr(piecewise, '_kernels', None)
    monkeypatch.setattr(piecewise, '_kernels_tried', False)
    with pytest.warns(RuntimeWarning, match=r'the compiled trajectory kernels did not load \(OSError: no writable '
                                            r'cache directory\); numpy samples and builds the splines'):
        assert trajectory.use_compiled_kernels() is False
    assert piecewise._kernels is None
    with warnings.catch_warnings():
        warnings.simplefilter('error')                 # asked again (another planner): tried once only
        assert trajectory.use_compiled_kernels() is False


def test_concatenate_composes_segments_and_refuses_a_gap():
    a = trajectory.cubic(0.0, 1.0, 1.0)
    b = trajectory.hold(1.0, 0.5)
    c = trajectory.lspb(1.0, 0.0, 2.0, 4.0)
    whole = trajectory.concatenate([a, b, c])
    assert whole.duration == pytest.approx(3.5)
    assert whole.sample([1.0, 1.25, 3.5])[0][:, 0] == pytest.approx([1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match='does not start where'):
        trajectory.concatenate([a, trajectory.cubic(2.0, 3.0, 1.0)])


@given(via_paths(), via_paths(), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
@settings(deadline=None)
def test_stacked_trajectories_keep_each_ones_motion(first, second, fractions):
    """Side by side over the union of their breaks, each trajectory moves as it did alone
    (pieces that now start inside one of its segments re-expanded, the others taken as they are)."""
    a = trajectory.via_lspb(first[0], first[1], 1e6)
    b = trajectory.via_lspb(second[0], second[1], 1e6)
    b = b.stretched(a.duration / b.duration)
    both = trajectory.stack([a, b])
    n = a.n_joints
    # Inside the pieces (at a break the acceleration of a blend may step), every piece at least once.
    times = np.concatenate([np.array(fractions) * a.duration, 0.5 * (both.breaks[1:] + both.breaks[:-1])])
    breaks = np.concatenate([a.breaks, b.breaks])
    times = times[np.abs(times[:, None] - breaks[None, :]).min(axis=1) > 1e-9 * a.duration]
    for alone, columns in ((a, slice(0, n)), (b, slice(n, None))):
        for x, y in zip(alone.sample(times), both.sample(times)):
            scale = 1.0 + np.abs(x).max()
            assert np.abs(y[:, columns] - x).max() <= 1e-9 * scale
    for x, y in zip(a.end_state(), a.sample(a.end_time)):
        assert x == pytest.approx(y[0], rel=1e-12, abs=1e-12)


@given(via_paths(), st.lists(st.floats(-0.5, 1.5), min_size=1, max_size=20))
@settings(deadline=None)
def test_state_at_is_sample_at_one_time(path, fractions):
    """The controller's per-tick fast path gives exactly what the vectorised sampler gives."""
    points, durations = path
    traj = trajectory.via_lspb(points, durations, 1e6)
    times = [f * traj.duration for f in fractions] + traj.breaks.tolist()
    for t in times:
        for fast, full in zip(traj.state_at(t), traj.sample(t)):
            assert fast == pytest.approx(full[0], rel=1e-12, abs=1e-9)


def test_a_stretched_trajectory_takes_longer_on_the_same_path_with_scaled_derivatives():
    from picking_core.trajectory import quintic
    traj = quintic([0.0, 1.0], [1.0, -2.0], 2.0).shifted(0.5)
    slow = traj.stretched(1.5)
    assert slow.start_time == 0.5 and slow.duration == pytest.approx(3.0)
    t = np.linspace(0.0, 2.0, 41)
    q, qd, qdd = traj.sample(0.5 + t)
    q2, qd2, qdd2 = slow.sample(0.5 + 1.5 * t)
    assert q2 == pytest.approx(q) and qd2 == pytest.approx(qd / 1.5) and qdd2 == pytest.approx(qdd / 1.5**2)
    assert slow.jerk(0.5 + 1.5 * t) == pytest.approx(traj.jerk(0.5 + t) / 1.5**3)
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError):
            traj.stretched(bad)


def test_quintic_via_free_ends_take_the_moving_samples_own_velocity_and_acceleration():
    # Samples of q = sin(2t) every 10 ms: a free end has the motion's own derivatives, a default end rests.
    t = np.linspace(0.0, 1.0, 101)
    q = np.sin(2.0 * t)[:, None]
    free = trajectory.quintic_via(q, np.diff(t), free_ends=(True, True))
    assert free.start_state()[1] == pytest.approx([2.0], abs=1e-5)
    assert free.start_state()[2] == pytest.approx([0.0], abs=1e-3)
    assert free.end_state()[1] == pytest.approx([2.0 * np.cos(2.0)], abs=1e-5)
    assert free.end_state()[2] == pytest.approx([-4.0 * np.sin(2.0)], rel=2e-3)
    half = trajectory.quintic_via(q, np.diff(t), free_ends=(False, True))
    assert half.start_state()[1] == pytest.approx([0.0]) and half.start_state()[2] == pytest.approx([0.0])
    assert half.end_state()[1] == pytest.approx([2.0 * np.cos(2.0)], abs=1e-5)


@given(via_paths(), st.floats(0.5, 50.0))
@settings(deadline=None)
def test_via_lspb_timing_is_the_trajectorys_without_building_it(path, accel):
    """The planner searches durations with the timing alone: the same blends and line
    speeds as the trajectory, the same refusal, and no faster point than its lines; built
    from that timing, the very same trajectory."""
    points, durations = path
    try:
        traj = trajectory.via_lspb(points, durations, accel)
    except ValueError as exc:
        with pytest.raises(ValueError, match=re.escape(str(exc))):
            trajectory.via_lspb_timing(points, durations, accel)
        return
    blends, velocities = trajectory.via_lspb_timing(points, durations, accel)
    assert np.array_equal(blends, traj.blend_times) and np.array_equal(velocities, traj.segment_velocities)
    again = trajectory.via_lspb(points, durations, accel, (blends, velocities))
    assert np.array_equal(again.breaks, traj.breaks) and np.array_equal(again.coeffs, traj.coeffs)
    qd = traj.sample(np.linspace(0.0, traj.duration, 2001))[1]
    assert np.all(np.abs(qd).max(axis=0) <= np.abs(velocities).max(axis=0) * (1 + 1e-9) + 1e-12)
