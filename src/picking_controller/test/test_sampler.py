"""The controller's sampler: the spline between points follows what the points carry."""

import numpy as np
import pytest

from picking_controller.sampler import from_points


def test_positions_only_can_be_linear_between_points_as_in_ros2_control():
    traj = from_points([0.0, 1.0, 3.0], [[0.0], [1.0], [5.0]], smooth_positions=False)
    q, qd, qdd = traj.sample([0.5, 2.0])
    assert q[:, 0] == pytest.approx([0.5, 3.0])
    assert qd[:, 0] == pytest.approx([1.0, 2.0])
    assert np.all(qdd == 0.0)


def test_with_velocities_is_cubic_through_positions_and_velocities():
    traj = from_points([0.0, 2.0], [[0.0, 1.0], [1.0, 0.0]], [[0.0, 0.0], [0.5, 0.0]])
    q, qd, _ = traj.sample([0.0, 2.0])
    assert q == pytest.approx(np.array([[0.0, 1.0], [1.0, 0.0]]))
    assert qd == pytest.approx(np.array([[0.0, 0.0], [0.5, 0.0]]))
    assert traj.coeffs[:, 4:].max() == 0.0 and traj.coeffs[:, 4:].min() == 0.0


def test_with_accelerations_is_quintic_meeting_all_three():
    traj = from_points([0.0, 1.0], [[0.0], [1.0]], [[0.0], [0.2]], [[0.0], [-1.0]])
    q, qd, qdd = traj.sample([1.0])
    assert (q[0, 0], qd[0, 0], qdd[0, 0]) == pytest.approx((1.0, 0.2, -1.0))


def test_a_later_first_point_splices_onto_the_current_state_without_a_jump():
    traj = from_points([1.0, 2.0], [[1.0], [2.0]], [[1.0], [0.0]], start=([0.2], [0.5], [0.0]))
    q, qd, qdd = traj.sample([0.0, 1.0])
    assert q[:, 0] == pytest.approx([0.2, 1.0])
    assert qd[:, 0] == pytest.approx([0.5, 1.0])
    t = np.linspace(0.0, 2.0, 2001)
    _, qd, _ = traj.sample(t)
    assert np.abs(np.diff(qd[:, 0])).max() < 0.01


def test_positions_only_are_smooth_by_default_and_do_not_overshoot():
    traj = from_points([0.0, 1.0, 2.0, 3.0], [[0.0], [1.0], [1.0], [2.0]])
    q, qd, qdd = traj.sample(np.linspace(0, 3, 3001))
    assert np.abs(np.diff(qd[:, 0])).max() < 0.01         # continuous velocity
    assert np.abs(np.diff(qdd[:, 0])).max() < 0.1         # continuous acceleration
    assert q[:, 0].min() >= -1e-12 and q[:, 0].max() <= 2.0 + 1e-12
    assert np.all(np.diff(q[:, 0]) >= -1e-12)             # monotone data stays monotone
    assert qd[-1, 0] == 0.0


@pytest.mark.parametrize('times, positions, match', [
    ([], np.zeros((0, 2)), 'at least one point'),
    ([0.0, 1.0, 1.0], np.zeros((3, 1)), 'increase strictly: point 2'),
    ([0.0, 2.0, 1.0], np.zeros((3, 1)), 'increase strictly'),
    ([0.0, 1.0], [[0.0], [np.nan]], 'finite'),
    ([0.0, 1.0], [[0.0, 1.0], [1.0]], 'positions'),
    ([-1.0, 1.0], np.zeros((2, 1)), '>= 0'),
])
def test_bad_trajectories_are_refused(times, positions, match):
    with pytest.raises(ValueError, match=match):
        from_points(times, positions)


def test_velocities_of_the_wrong_size_are_refused():
    with pytest.raises(ValueError, match='velocities'):
        from_points([0.0, 1.0], np.zeros((2, 2)), np.zeros((2, 3)))


def test_two_points_a_microsecond_apart_are_one_instant_where_the_acceleration_steps():
    """Constant acceleration 2, then -2 from t = 1 s (an LSPB's blend ending): exactly, no overshoot."""
    q1, v1 = 1.0, 2.0
    e = 1e-6                                   # the second point: the state a microsecond after the step
    traj = from_points([0.0, 1.0, 1.0 + e, 2.0], [[0.0], [q1], [q1 + v1 * e - e * e], [q1 + v1 - 1.0]],
                       [[0.0], [v1], [v1 - 2 * e], [0.0]], [[2.0], [2.0], [-2.0], [-2.0]])
    t = np.linspace(0.0, 2.0, 2001)
    q, qd, qdd = traj.sample(t)
    assert qdd[t <= 1.0, 0] == pytest.approx(2.0) and qdd[t > 1.0, 0] == pytest.approx(-2.0)
    assert q[:, 0] == pytest.approx(np.where(t <= 1.0, t * t, q1 + v1 * (t - 1) - (t - 1) ** 2))
    # Points further apart are two instants: a quintic joins them as before.
    apart = from_points([0.0, 1.0, 1.01, 2.0], [[0.0], [q1], [q1 + 0.02], [q1 + v1 - 1.0]],
                        [[0.0], [v1], [v1], [0.0]], [[2.0], [2.0], [-2.0], [-2.0]])
    assert len(apart.breaks) == 4
