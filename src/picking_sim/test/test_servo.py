"""The servo loop of Fig. 1: tracking, holding, saturation, and the silent-controller guard."""

import numpy as np
import pytest

from picking_core import trajectory
from picking_sim.servo import Servo, ServoParams


def run(servo, traj, t_end):
    t = np.arange(0.0, t_end, servo.dt)
    q, qd, qdd = traj.sample(t)
    errors = []
    for i in range(len(t)):
        servo.command(q[i], qd[i], qdd[i])
        servo.step()
        errors.append(np.abs(servo.q - traj.sample(t[i] + servo.dt)[0][0]))
    return np.array(errors)


def test_fig1_loop_tracks_a_quintic_with_feedforward_within_a_hundredth_of_a_degree():
    servo = Servo(np.zeros(3), params=ServoParams(max_velocity=3.0))
    traj = trajectory.quintic(np.zeros(3), [1.0, -0.6, 0.4], 2.0)
    errors = run(servo, traj, 2.5)
    assert np.degrees(errors.max()) < 0.01
    assert np.degrees(errors[-1].max()) < 0.001


def test_late_commands_are_moved_on_to_the_servo_time():
    # Each command arrives 3 ms after it was sampled (transport delay): with its age the
    # servo tracks as if it had none; without, it lags by velocity x delay.
    traj = trajectory.quintic(np.zeros(2), [1.5, -1.0], 1.0)
    delay = 0.003
    worst = {}
    for use_age in (True, False):
        servo = Servo(np.zeros(2), params=ServoParams(max_velocity=5.0))
        t = np.arange(0.0, 1.2, servo.dt)
        q, qd, qdd = traj.sample(np.maximum(t - delay, 0.0))
        err = []
        for i in range(len(t)):
            servo.command(q[i], qd[i], qdd[i], age=delay if use_age else 0.0)
            servo.step()
            err.append(np.abs(servo.q - traj.sample(t[i] + servo.dt)[0][0]).max())
        worst[use_age] = np.degrees(max(err))
    assert worst[True] < 0.02
    assert worst[False] > 0.1


def test_stale_or_bad_ages_are_not_extrapolated():
    servo = Servo([0.0], command_timeout=0.05)
    for age in (np.nan, -1.0, 0.2):
        servo.command([1.0], [2.0], [0.0], age=age)
        assert servo.ref_q[0] == 1.0


@pytest.mark.parametrize('move, stall', [
    ((1.0, 1.0), 0.08),
    ((1.5, 0.6), 0.08),
    ((1.5, 0.6), 0.2),          # a brisk move: taken back in time the command was 7 degrees off
    ((1.5, 0.8), 0.35),         # as long as the middleware was seen to block a publish
])
def test_a_servo_catching_up_after_a_stall_follows_the_commands_not_ahead_of_them(move, stall):
    # The servo's thread stalls at 0.2 s; it wakes with its clock still at 0.2 s and the newest
    # command sampled `stall` s later (in its future), and runs the missed steps at once.
    distance, duration = move
    traj = trajectory.quintic(np.zeros(1), [distance], duration)
    servo = Servo(np.zeros(1), params=ServoParams(max_velocity=5.0), command_timeout=0.05)
    worst, steps = 0.0, int(round((duration + 0.2) / servo.dt))
    missed = int(round(stall / servo.dt))
    k = 0
    while k < steps:
        t = k * servo.dt
        stalled = abs(t - 0.2) < servo.dt / 2
        sampled = t + stall if stalled else t
        q, qd, qdd = (x[0] for x in traj.sample(np.array([sampled])))
        servo.command(q, qd, qdd, age=t - sampled)
        for _ in range(missed if stalled else 1):
            servo.step()
            k += 1
            worst = max(worst, abs(servo.q[0] - traj.sample(np.array([k * servo.dt]))[0][0, 0]))
            assert servo.commanded                    # catching up is not "no commands"
    assert np.degrees(worst) < 0.05


def test_the_catch_up_ends_on_the_command_then_moves_on_from_it():
    servo = Servo(np.zeros(2), command_timeout=0.05)
    servo.command([0.1, -0.2], [1.0, 0.5], [2.0, 0.0], age=-0.03)     # 30 steps in the servo's future
    servo.step(29)
    assert servo.ref_q != pytest.approx([0.1, -0.2])
    servo.step()
    assert servo.ref_q == pytest.approx([0.1, -0.2], abs=1e-12) and servo.ref_qd == pytest.approx([1.0, 0.5])
    assert servo.ref_qdd == pytest.approx([2.0, 0.0], abs=1e-9)
    servo.step(10)                                                     # then on with its velocity
    assert servo.ref_q == pytest.approx([0.1 + 0.01 + 0.5 * 2.0 * 1e-4, -0.2 + 0.005], abs=1e-9)
    servo.step(60)
    assert not servo.commanded and servo.ref_qd == pytest.approx([0.0, 0.0])


def test_holds_its_position_without_commands():
    servo = Servo([0.3, -0.2])
    servo.step(2000)
    assert servo.q == pytest.approx([0.3, -0.2], abs=1e-12)


def test_reference_stops_moving_when_commands_stop():
    servo = Servo([0.0], dt=1e-3, command_timeout=0.05)
    servo.command([0.0], [1.0], [0.0])
    servo.step(1000)                                 # a full second without another command
    assert servo.ref_qd[0] == 0.0
    assert 0.04 < servo.ref_q[0] < 0.06              # moved on for 50 ms only
    assert abs(servo.q[0] - servo.ref_q[0]) < 1e-3


def test_velocity_and_torque_saturate():
    servo = Servo([0.0], params=ServoParams(max_velocity=0.5, max_torque=5.0))
    servo.command([2.0])
    qd_seen = []
    for _ in range(3000):
        servo.step()
        qd_seen.append(servo.qd[0])
        assert abs(servo.torque[0]) <= 5.0 + 1e-12
    assert max(qd_seen) <= 0.5 + 1e-12
    assert 1.0 < servo.q[0] < 1.5 + 1e-9            # 3 s at no more than 0.5 rad/s


@pytest.mark.parametrize('field, value', [('bandwidth', 0.0), ('inertia', -1.0), ('friction', np.nan)])
def test_bad_parameters_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        Servo([0.0], params=ServoParams(**{field: value}))


@pytest.mark.parametrize('dt, timeout, reason', [
    (0.0, 0.05, 'servo period must be > 0 s'), (1e-3, np.nan, 'command_timeout must be > 0 s'),
    (1e-3, 0.0, 'command_timeout must be > 0 s'), (2.2e-313, 0.05, 'servo period 2.2e-313 s is too short')])
def test_bad_periods_and_timeouts_are_refused(dt, timeout, reason):
    with pytest.raises(ValueError, match=reason):
        Servo([0.0], dt=dt, command_timeout=timeout)


def test_bad_commands_are_refused():
    servo = Servo([0.0, 0.0])
    with pytest.raises(ValueError):
        servo.command([np.nan, 0.0])
    with pytest.raises(ValueError):
        servo.command([0.0])


def test_a_servo_woken_late_waits_briefly_for_a_command_sent_during_its_stall():
    from types import SimpleNamespace

    from builtin_interfaces.msg import Time

    from picking_sim.node import newest_since

    def msg(t):
        return SimpleNamespace(header=SimpleNamespace(stamp=Time(sec=int(t), nanosec=int(round(t % 1 * 1e9)))))
    old, fresh = msg(10.0), msg(10.3)
    arrivals = iter([old, old, old, fresh])           # the middleware takes the new one in a little later
    assert newest_since(lambda: next(arrivals), 10.25, 1.0) is fresh
    # None comes (the controller stalled too): the newest there is, after the wait.
    assert newest_since(lambda: old, 10.25, 0.005) is old
    assert newest_since(lambda: None, 10.25, 0.0) is None


def test_a_joint_closing_on_a_stop_rests_there_and_moves_freely_once_it_is_lifted():
    """Fingers closing on an apple: they stop at its width (not past it, not wound up), then open at once."""
    servo = Servo([0.09], dt=1e-3, command_timeout=10.0)
    servo.stop_at(0, 0.08)
    servo.command([0.055])
    servo.step(500)
    assert servo.q[0] == pytest.approx(0.08) and servo.qd[0] == 0.0
    servo.stop_at(0, -np.inf)
    servo.command([0.09])
    servo.step(500)
    opened = servo.q[0]
    free = Servo([0.08], dt=1e-3, command_timeout=10.0)
    free.command([0.09])
    free.step(500)
    assert opened == pytest.approx(free.q[0], abs=1e-4)        # as fast as fingers that never pressed
    servo.command([0.055])
    servo.step(1000)
    assert servo.q[0] == pytest.approx(0.055, abs=5e-4)       # closing freely on air
