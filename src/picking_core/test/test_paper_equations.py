"""The paper's worked examples, each test named for the equation or figure it checks.

Angles are in degrees, as printed in the paper; the core is unit-agnostic.
"""

import numpy as np
import pytest

from picking_core import geometry, trajectory


def test_eq20_minimum_lspb_acceleration_is_26_67_deg_s2():
    assert trajectory.min_lspb_accel(15.0, 75.0, 3.0)[0] == pytest.approx(26.6667, abs=1e-4)


def test_eq20_below_minimum_is_refused_with_the_minimum_named():
    with pytest.raises(ValueError, match=r'26\.6667'):
        trajectory.lspb(15.0, 75.0, 3.0, 26.0)


def test_one_joint_given_as_plain_numbers_has_plain_float_attributes():
    seg = trajectory.lspb(15.0, 75.0, 3.0, 42.0)
    for name in ('blend_time', 'blend_position', 'cruise_velocity', 'accel', 'min_accel'):
        assert type(getattr(seg, name)) is float, name
    assert float(seg.blend_time) == seg.blend_time
    assert seg.sample([0.0, 1.0])[0].shape == (2, 1)
    assert trajectory.lspb([15.0], [75.0], 3.0, 42.0).blend_time.shape == (1,)


def test_eq20_exactly_the_minimum_gives_the_triangular_profile():
    seg = trajectory.lspb(15.0, 75.0, 3.0, 4.0 * 60.0 / 9.0)
    assert seg.blend_time == pytest.approx(1.5)
    q, qd, _ = seg.sample([1.5])
    assert q[0, 0] == pytest.approx(45.0)
    assert qd[0, 0] == pytest.approx(40.0)          # peak = accel * tf / 2


def test_eq19_eq16_blend_at_42_deg_s2():
    seg = trajectory.lspb(15.0, 75.0, 3.0, 42.0)
    assert seg.blend_time == pytest.approx(0.594, abs=5e-4)        # paper: 0.59 s
    assert seg.blend_position == pytest.approx(22.4, abs=5e-3)     # paper: 22.3 deg (rounded t_a)
    assert seg.cruise_velocity == pytest.approx(24.93, abs=5e-3)
    q, qd, qdd = seg.sample([0.0, seg.blend_time, 1.5, 3.0])
    assert q[:, 0] == pytest.approx([15.0, 22.4014, 45.0, 75.0], abs=1e-3)
    assert qd[[0, -1], 0] == pytest.approx([0.0, 0.0], abs=1e-12)


def test_eq19_blend_at_27_deg_s2():
    seg = trajectory.lspb(15.0, 75.0, 3.0, 27.0)
    assert seg.blend_time == pytest.approx(4.0 / 3.0)             # paper: 1.33 s
    assert seg.blend_position == pytest.approx(39.0)               # paper: 38.88 deg
    assert seg.cruise_velocity == pytest.approx(36.0)              # paper: 35.91 deg/s


def test_fig9_two_joints_move_in_one_synchronised_duration():
    seg = trajectory.lspb([15.0, 15.0], [75.0, 75.0], 3.0, [42.0, 27.0])
    assert seg.duration == 3.0
    q, qd, _ = seg.sample([0.0, 3.0])
    assert q == pytest.approx(np.array([[15.0, 15.0], [75.0, 75.0]]))
    assert seg.blend_time == pytest.approx([0.5937, 4.0 / 3.0], abs=1e-4)


def test_eq11_cubic_15_to_75_in_3_s():
    seg = trajectory.cubic(15.0, 75.0, 3.0)
    a0, a1, a2, a3 = seg.coeffs[0, :4, 0]
    assert (a0, a1) == (15.0, 0.0)
    assert a2 == pytest.approx(20.0)
    assert a3 == pytest.approx(-4.4444, abs=1e-4)
    t = np.linspace(0.0, 3.0, 3001)
    _, qd, _ = seg.sample(t)
    assert qd.max() == pytest.approx(30.0)
    assert t[np.argmax(qd)] == pytest.approx(1.5)


def test_eq14_cubic_0_to_90_in_3_s_follows_eq11_not_the_printed_numbers():
    # Eq. 11 gives a2 = 3*90/9 = 30 and a3 = -2*90/27 = -6.67; the paper prints
    # 2.35 and -1.63 (Eq. 14), which do not reach 90 deg at 3 s. Formulas win.
    seg = trajectory.cubic(0.0, 90.0, 3.0)
    assert seg.coeffs[0, 2, 0] == pytest.approx(30.0)
    assert seg.coeffs[0, 3, 0] == pytest.approx(-6.6667, abs=1e-4)
    printed = 2.35 * 3.0**2 - 1.63 * 3.0**3
    assert abs(printed - 90.0) > 50.0
    assert seg.sample(3.0)[0][0, 0] == pytest.approx(90.0)


def test_eq13_cubic_velocity_and_acceleration():
    seg = trajectory.cubic(0.0, 90.0, 3.0)
    t = np.linspace(0.0, 3.0, 31)
    _, qd, qdd = seg.sample(t)
    h = 90.0
    assert qd[:, 0] == pytest.approx(6 * h / 9 * t - 6 * h / 27 * t**2)
    assert qdd[:, 0] == pytest.approx(6 * h / 9 - 12 * h / 27 * t)


def test_sec3_1_arc_through_p1_p2_p3_with_45_insertion_points():
    arc = geometry.Arc.through((10, 3, 4), (11, 3, 5), (10, 3, 6))
    assert arc.center == pytest.approx([10.0, 3.0, 5.0])
    assert arc.radius == pytest.approx(1.0)
    assert arc.sweep == pytest.approx(np.pi)
    pts = arc.points(47)                               # P1 + 45 insertion points + P3
    assert np.linalg.norm(pts - arc.center, axis=1) == pytest.approx(np.ones(47))
    assert pts[0] == pytest.approx([10, 3, 4])
    assert pts[-1] == pytest.approx([10, 3, 6])
    assert pts[23] == pytest.approx([11, 3, 5])       # P2 lies on the path
    assert np.abs(pts[:, 1] - 3.0).max() < 1e-12      # the arc's plane y = 3


def test_eq4_eq5_frame_and_its_corrected_inverse():
    arc = geometry.Arc.through((10, 3, 4), (11, 3, 5), (10, 3, 6))
    assert arc.frame @ arc.frame_inverse == pytest.approx(np.eye(4))
    assert arc.frame[:3, 3] == pytest.approx([10, 3, 4])          # origin at P1
    assert arc.frame[:3, 2] == pytest.approx([0, 0, 1])           # Z_R along P1P3
    # In {R} every arc point has y_R = 0: the arc lies in the X_R Z_R plane.
    homog = np.c_[arc.points(20), np.ones(20)]
    assert np.abs((arc.frame_inverse @ homog.T)[1]).max() < 1e-12


def test_sec3_2_denser_interpolation_approaches_the_arc():
    arc = geometry.Arc.through((10, 3, 4), (11, 3, 5), (10, 3, 6))
    errors = [arc.chord_error(n) for n in (5, 10, 47, 100, 1000)]
    assert errors == sorted(errors, reverse=True)
    # Measured: the distance from the arc's midpoints between samples to the polyline.
    n = 47
    pts = arc.points(n)
    mid = arc.at((np.arange(n - 1) + 0.5) * arc.length / (n - 1))[0]
    chord_mid = 0.5 * (pts[1:] + pts[:-1])
    assert np.linalg.norm(mid - chord_mid, axis=1).max() == pytest.approx(arc.chord_error(n))


SEC_3_1_D = dict(
    points=[[0, 0, 0], [-11.2, 9.4, -109.6], [13.2, -10.8, -99.3], [0, 0, 0]],
    velocities=[[0, 0, 0], [-9.3, 13.4, 134.1], [-15.4, 16.2, 164.2], [0, 0, 0]],
    accelerations=[[0, 0, 0], [-13.5, 27.4, 104.3], [-17.2, 21.1, 114.7], [0, 0, 0]],
)


def test_sec3_1_step_d_via_points_with_velocities_and_accelerations():
    path = trajectory.quintic_via(SEC_3_1_D['points'], 2.0, SEC_3_1_D['velocities'],
                                  SEC_3_1_D['accelerations'])
    assert path.duration == 6.0
    q, qd, qdd = path.sample([0.0, 2.0, 4.0, 6.0])
    assert q == pytest.approx(np.array(SEC_3_1_D['points'], float), abs=1e-9)
    assert qd == pytest.approx(np.array(SEC_3_1_D['velocities'], float), abs=1e-9)
    assert qdd == pytest.approx(np.array(SEC_3_1_D['accelerations'], float), abs=1e-9)
    # Sampled every 0.01 s (step E): continuous position, velocity, acceleration.
    t = np.arange(0.0, 6.0 + 1e-9, 0.01)
    q, qd, qdd = path.sample(t)
    for k in (200, 400):                             # the joins at 2 s and 4 s
        left = path.sample(t[k] - 1e-9)
        right = path.sample(t[k] + 1e-9)
        for a, b in zip(left, right):
            assert a == pytest.approx(b, abs=1e-5)
    # No step at a join is larger than the steps inside the segments around it.
    steps = np.abs(np.diff(qdd, axis=0)).max(axis=1)
    for k in (200, 400):
        assert steps[k - 1:k + 1].max() <= 1.05 * max(steps[k - 50:k - 1].max(), steps[k + 1:k + 50].max())


def test_fig12_via_lspb_reaches_first_and_last_points_and_rounds_the_interior_ones():
    points = [[15.0], [75.0], [30.0], [60.0]]
    path = trajectory.via_lspb(points, [3.0, 2.0, 2.0], 200.0)
    q, qd, _ = path.sample([0.0, 7.0])
    assert q[:, 0] == pytest.approx([15.0, 60.0])
    assert qd[:, 0] == pytest.approx([0.0, 0.0], abs=1e-9)
    # Interior via points are approached, close for a large acceleration.
    q_via, _, _ = path.sample([3.0, 5.0])
    assert abs(q_via[0, 0] - 75.0) < 3.0 and abs(q_via[1, 0] - 30.0) < 3.0
    assert abs(q_via[0, 0] - 75.0) > 0.0


def test_fig12_via_lspb_segment_too_short_for_its_blends():
    with pytest.raises(ValueError, match='too short for its blends'):
        trajectory.via_lspb([[0.0], [90.0], [0.0], [90.0]], [1.0, 0.2, 1.0], 200.0)
