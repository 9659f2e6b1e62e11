"""Lines, arcs and timed Cartesian paths."""

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from picking_core import geometry

coord = st.floats(-5.0, 5.0, allow_nan=False)
point = st.tuples(coord, coord, coord).map(np.array)


@given(point, point, point)
def test_arc_passes_its_three_points_and_stays_on_its_circle(p1, p2, p3):
    a, b = p2 - p1, p3 - p1
    assume(min(np.linalg.norm(a), np.linalg.norm(b), np.linalg.norm(p3 - p2)) > 1e-2)
    assume(np.linalg.norm(np.cross(a, b)) > 1e-2 * np.linalg.norm(a) * np.linalg.norm(b))
    arc = geometry.Arc.through(p1, p2, p3)
    pts = arc.points(2001)
    assert pts[0] == pytest.approx(p1, abs=1e-9)
    assert pts[-1] == pytest.approx(p3, abs=1e-9)
    assert np.linalg.norm(pts - arc.center, axis=1) == pytest.approx(np.full(2001, arc.radius))
    assert np.abs((pts - arc.center) @ arc.normal).max() < 1e-9 * max(1.0, arc.radius)
    # p2 lies on the path between p1 and p3.
    assert np.linalg.norm(pts - p2, axis=1).min() < arc.length / 2000 + 1e-9


def test_arc_beyond_180_degrees():
    # p2 on the far side: from (1,0,0) through (0,-1,0) to (0,1,0) around the unit circle.
    arc = geometry.Arc.through((1, 0, 0), (0, -1, 0), (0, 1, 0))
    assert arc.sweep == pytest.approx(1.5 * np.pi)
    assert arc.normal == pytest.approx([0, 0, -1])
    mid = arc.at(arc.length / 3)[0][0]
    assert mid == pytest.approx([0.0, -1.0, 0.0], abs=1e-12)


@pytest.mark.parametrize('pts, match', [
    (((0, 0, 0), (1, 1, 1), (2, 2, 2)), 'collinear'),
    (((0, 0, 0), (1, 0, 0), (1 + 1e-13, 1e-14, 0)), 'distinct|collinear'),
    (((0, 0, 0), (0, 0, 0), (1, 0, 0)), 'distinct'),
    (((0, 0, 0), (1, float('nan'), 0), (1, 0, 0)), 'finite'),
    (((0, 0, 0), (1, 0), (1, 0, 0)), 'three numbers'),
])
def test_arc_refuses_collinear_repeated_and_non_finite_points(pts, match):
    with pytest.raises(ValueError, match=match):
        geometry.Arc.through(*pts)


def test_arc_derivatives_are_unit_tangent_and_centripetal():
    arc = geometry.Arc.through((0, 0, 0), (1, 1, 0.5), (2, 0, 1))
    s = np.linspace(0, arc.length, 50)
    p, dp, ddp = arc.at(s)
    assert np.linalg.norm(dp, axis=1) == pytest.approx(np.ones(50))
    assert np.linalg.norm(ddp, axis=1) == pytest.approx(np.full(50, 1 / arc.radius))
    h = 1e-6
    numeric = (arc.at(s[1:-1] + h)[0] - arc.at(s[1:-1] - h)[0]) / (2 * h)
    assert numeric == pytest.approx(dp[1:-1], abs=1e-6)


def test_line_points_and_zero_length_line():
    line = geometry.Line((0, 0, 0), (0.3, 0.4, 0))
    assert line.length == pytest.approx(0.5)
    assert line.points(3)[1] == pytest.approx([0.15, 0.2, 0.0])
    still = geometry.Line((1, 2, 3), (1, 2, 3))
    assert still.length == 0.0 and still.points(4) == pytest.approx(np.tile([1, 2, 3], (4, 1)))


@pytest.mark.parametrize('profile', geometry.PROFILES)
def test_cartesian_line_traversed_by_each_profile(profile):
    line = geometry.Line((0.5, 0.0, 0.3), (0.5, 0.2, 0.3))
    path = geometry.CartesianPath.timed(line, 2.0, profile)
    t = np.linspace(0.0, 2.0, 201)
    p, v, a = path.sample(t)
    assert p[0] == pytest.approx(line.start) and p[-1] == pytest.approx(line.end)
    assert v[[0, -1]] == pytest.approx(np.zeros((2, 3)), abs=1e-12)
    assert np.abs(p[:, [0, 2]] - [0.5, 0.3]).max() < 1e-12   # stays on the line
    assert np.all(np.diff(p[:, 1]) >= -1e-15)
    numeric = np.gradient(p[:, 1], t)
    assert numeric[5:-5] == pytest.approx(v[5:-5, 1], abs=2e-3)


def test_cartesian_arc_velocity_is_tangent_and_orientation_is_slerped():
    arc = geometry.Arc.through((0.5, 0, 0.3), (0.6, 0.1, 0.3), (0.5, 0.2, 0.3))
    q0 = Rotation.from_euler('xyz', [180, 0, 0], degrees=True)
    q1 = Rotation.from_euler('xyz', [180, 0, 90], degrees=True)
    path = geometry.CartesianPath.timed(arc, 1.5, 'lspb',
                                        orientations=Rotation.concatenate([q0, q1]))
    t = np.linspace(0, 1.5, 151)
    p, v, _ = path.sample(t)
    assert np.abs(np.einsum('ij,ij->i', v, p - arc.center)).max() < 1e-12
    rots = path.orientations(t)
    assert (rots[0] * q0.inv()).magnitude() < 1e-9
    assert (rots[-1] * q1.inv()).magnitude() < 1e-9
    assert (rots[75] * q0.inv()).magnitude() == pytest.approx(np.pi / 4, abs=1e-9)
    poses = path.poses(t)
    assert poses.shape == (151, 4, 4) and poses[-1, :3, 3] == pytest.approx([0.5, 0.2, 0.3])


def test_cartesian_path_refuses_bad_profile_and_quaternions():
    line = geometry.Line((0, 0, 0), (1, 0, 0))
    with pytest.raises(ValueError, match='unknown profile'):
        geometry.CartesianPath.timed(line, 1.0, 'septic')
    with pytest.raises(ValueError, match='non-zero'):
        geometry.CartesianPath.timed(line, 1.0, orientations=[[0, 0, 0, 0]])


@given(st.integers(2, 5), st.integers(0, 2**32 - 1), st.sampled_from(['rotation', 'quaternions', 'matrices']))
def test_cartesian_path_orientations_are_scipys_slerp_between_its_keys(k, seed, given_as):
    rng = np.random.default_rng(seed)
    rots = Rotation.random(k, random_state=seed)
    keys = np.concatenate(([0.0], np.sort(rng.uniform(0.05, 0.95, k - 2)), [1.0]))
    assume(np.diff(keys).min() > 1e-3)
    orientations = {'rotation': rots, 'quaternions': rots.as_quat() * rng.uniform(0.5, 2.0),
                    'matrices': rots.as_matrix()}[given_as]
    path = geometry.CartesianPath(geometry.Line((0, 0, 0), (1, 0, 0)), geometry.progress_profile(1.0, 'cubic'),
                                  orientations, keys)
    t = np.concatenate((np.linspace(0.0, 1.0, 97), keys))      # the keys themselves too
    u = path.profile.sample(t)[0][:, 0]
    expected = Slerp(keys, rots)(np.clip(u, 0.0, 1.0)).as_matrix()
    assert np.abs(path.poses(t)[:, :3, :3] - expected).max() < 1e-12
    assert np.abs(path.orientations(t).as_matrix() - expected).max() < 1e-12


@pytest.mark.parametrize('angle, held', [(0.0, True), (1e-13, True), (1e-9, False)])
def test_key_orientations_equal_to_rounding_are_held_and_any_turn_beyond_is_slerped(angle, held):
    # A line whose tool keeps its orientation, its start pose from FK: nothing to slerp at every sample.
    R0 = Rotation.from_euler('xyz', [0.3, -0.2, 1.1])
    R1 = R0 * Rotation.from_rotvec([0.0, 0.0, angle])
    path = geometry.CartesianPath.timed(geometry.Line((0, 0, 0), (0, 0, 0.06)), 0.4,
                                        orientations=np.stack([R0.as_matrix(), R1.as_matrix()]))
    t = np.linspace(0.0, 0.4, 41)
    expected = Slerp([0.0, 1.0], Rotation.concatenate([R0, R1]))(path.profile.sample(t)[0][:, 0].clip(0, 1))
    assert (path._fixed is not None) == held
    assert np.abs(path.poses(t)[:, :3, :3] - expected.as_matrix()).max() < 1e-12


def test_cartesian_path_refuses_orientation_matrices_that_are_not_rotations():
    line = geometry.Line((0, 0, 0), (1, 0, 0))
    mirror = np.diag([1.0, 1.0, -1.0])
    for bad in ([np.eye(3), mirror], [np.eye(3), 1.01 * np.eye(3)]):
        with pytest.raises(ValueError, match='proper rotation'):
            geometry.CartesianPath.timed(line, 1.0, orientations=np.array(bad))
    with pytest.raises(ValueError, match='finite'):
        geometry.CartesianPath.timed(line, 1.0, orientations=np.array([np.eye(3), np.full((3, 3), np.nan)]))
    fixed = geometry.CartesianPath.timed(line, 1.0, orientations=[Rotation.from_euler('x', 0.3).as_matrix()])
    assert fixed.poses(np.array([0.0, 0.7]))[:, :3, :3] == pytest.approx(
        np.repeat(Rotation.from_euler('x', 0.3).as_matrix()[None], 2, axis=0), abs=1e-15)


def test_optimal_progress_is_bang_bang_jerk_and_faster_than_a_quintic_for_the_same_peak_jerk():
    T = 1.0
    fast = geometry.progress_profile(T, 'optimal')
    t = np.linspace(0.0, T, 4001)
    jerk = fast.jerk(t)[:, 0]
    # +J, -J, +J with switches at T/4 and 3T/4 (jerk-bound, rest to rest): h = J T^3 / 32.
    assert np.abs(jerk[[100, 2000, 3900]] - np.array([32.0, -32.0, 32.0])).max() < 1e-6
    q, qd, _ = fast.sample(np.array([0.0, T]))
    assert q[:, 0] == pytest.approx([0.0, 1.0]) and qd[:, 0] == pytest.approx([0.0, 0.0], abs=1e-12)
    # For the same peak jerk a quintic needs (60/32)^(1/3) = 1.23 times as long.
    quintic = geometry.progress_profile(T, 'quintic')
    assert np.abs(quintic.jerk(t)).max() == pytest.approx(60.0, rel=1e-3)


def test_optimal_progress_within_given_limits_keeps_them_and_reaches_one():
    limits = (2.0, 10.0, 100.0)
    shape = geometry.optimal_progress(limits)
    t = np.linspace(0.0, shape.duration, 2001)
    q, qd, qdd = shape.sample(t)
    assert q[-1, 0] == pytest.approx(1.0) and np.abs(qd).max() <= 2.0 + 1e-9
    assert np.abs(qdd).max() <= 10.0 + 1e-9 and np.abs(shape.jerk(t)).max() <= 100.0 + 1e-6
    slower = geometry.progress_profile(2.0 * shape.duration, 'optimal', limits=limits)
    assert slower.duration == pytest.approx(2.0 * shape.duration)
    assert slower.sample(t * 2.0)[0] == pytest.approx(q)                # the same shape, stretched


def test_a_stretched_cartesian_path_passes_the_same_poses_later():
    arc = geometry.Arc.through((0.5, 0, 0.3), (0.6, 0.1, 0.3), (0.5, 0.2, 0.3))
    rots = Rotation.from_euler('xyz', [[180, 0, 0], [180, 0, 90]], degrees=True)
    path = geometry.CartesianPath.timed(arc, 1.5, 'quintic', orientations=rots)
    slow = path.stretched(1.3)
    t = np.linspace(0.0, 1.5, 31)
    assert slow.duration == pytest.approx(1.95)
    assert slow.poses(1.3 * t) == pytest.approx(path.poses(t), abs=1e-12)
    (_, v, a), (_, v_slow, a_slow) = path.sample(t), slow.sample(1.3 * t)
    assert v_slow == pytest.approx(v / 1.3, abs=1e-12) and a_slow == pytest.approx(a / 1.3**2, abs=1e-12)
