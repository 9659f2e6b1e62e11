"""Row 12: the UR5e and the FR3 (issue 46): their IK against roboticstoolbox's numeric IK on the same
poses, and the Table 1 cycle planned on each arm."""

from __future__ import annotations

import numpy as np
from harness import fmt_time, median, p99, time_calls
from scipy.spatial.transform import Rotation

from picking_core.kinematics import ArmModel, pose_matrix
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import Planner, PlannerSettings
from picking_description import urdf_path

N_SINGLE = 200
N_BATCH = 100_000
N_ACCURACY = 10_000
N_NUMERIC = 1000
N_PEER = 100
GRASP = 0.15                 # tool0 beyond the flange in the shipped descriptions
HOMES = {'ur5e': (3.14, -2.04, 2.02, 0.02, 1.57, -1.57), 'fr3': (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)}
APPLE = pose_matrix([0.6, 0.15, 0.6], Rotation.from_euler('y', 90, degrees=True).as_quat())


def _peer(name, arm):
    """The same arm in roboticstoolbox (its published Denavit-Hartenberg table), or None."""
    try:
        import roboticstoolbox as rtb
        from spatialmath import SE3
    except ImportError:
        return None
    limits = np.stack([arm.lower, arm.upper])
    if name == 'ur5e':
        d, a = (0.1625, 0, 0, 0.1333, 0.0997, 0.0996), (0, -0.425, -0.3922, 0, 0, 0)
        alpha = (np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0)
        links = [rtb.RevoluteDH(d=d[i], a=a[i], alpha=alpha[i], qlim=limits[:, i]) for i in range(6)]
        return rtb.DHRobot(links, tool=SE3.Tz(GRASP), name='UR5e')
    a, d = (0, 0, 0, 0.0825, -0.0825, 0, 0.088), (0.333, 0, 0.316, 0, 0.384, 0, 0)
    alpha = (0, -np.pi / 2, np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, np.pi / 2)
    links = [rtb.RevoluteMDH(a=a[i], d=d[i], alpha=alpha[i], qlim=limits[:, i]) for i in range(7)]
    return rtb.DHRobot(links, tool=SE3.Tz(0.107 + GRASP), name='FR3')


def _peer_ratio(peer, arm, T, seeds, ours_per_pose, repeats):
    """rtb's ikine_LM on the first N_PEER poses from the same seeds: its time a pose over ours, and how many it solved."""
    if peer is None:
        return 'rtb: not installed'
    ets = peer.ets()                  # its compiled Levenberg-Marquardt (C++), the fastest it has
    solved = []

    def run():
        solved[:] = [ets.ik_LM(t, q0=q, joint_limits=True).success for t, q in zip(T[:N_PEER], seeds[:N_PEER])]
    times = time_calls({'peer': run}, repeats=max(2, repeats // 5), warmup=1)['peer'] / N_PEER
    return (f'rtb ik_LM (residual 1e-6) {fmt_time(median(times))} a pose ({sum(solved)}/{N_PEER} solved): '
            f'{median(times) / ours_per_pose:.1f}x ours')


def _ik_rows(name, repeats):
    arm = ArmModel.from_urdf(urdf_path(name))
    arm.load_ik()
    rng = np.random.default_rng(46)
    Q = rng.uniform(arm.lower, arm.upper, (N_BATCH, arm.dof))
    T = np.ascontiguousarray(arm.fk(Q))
    near = np.ascontiguousarray(np.clip(Q + rng.normal(0.0, 0.05, Q.shape), arm.lower, arm.upper))
    peer = _peer(name, arm)
    rows = []
    if name == 'ur5e':
        def one():
            for i in range(N_SINGLE):
                arm.ik(T[i], near[i])
        per = time_calls({'one': one}, repeats=repeats, warmup=1)['one'] / N_SINGLE
        batch = time_calls({'batch': lambda: arm.ik_batch(T, near)}, repeats=max(3, repeats // 3), warmup=1)['batch']
        rate = N_BATCH / median(batch)
        q, ok, _ = arm.ik_batch(T[:N_ACCURACY], near[:N_ACCURACY])
        err = np.abs(arm.fk(q[ok])[:, :3, 3] - T[:N_ACCURACY][ok][:, :3, 3]).max()
        accurate = ok.all() and err <= 1e-9
        rows += [
            ['12', 'UR5e IK one pose (closed form, compiled)', f'{fmt_time(median(per))} (p99 {fmt_time(p99(per))})',
             _peer_ratio(peer, arm, T, near, median(per), repeats), '≤ 10 µs', 'met' if median(per) <= 10e-6 else 'missed'],
            ['12', f'UR5e IK batched ({N_BATCH:,} poses)', f'{rate:,.0f} poses/s',
             f'{N_ACCURACY:,} random reachable: {ok.sum():,} solved, worst {err:.1e} m', '≥ 500,000 poses/s, all to 1e-9 m',
             'met' if rate >= 500_000 and accurate else 'missed']]
        return rows
    n = N_NUMERIC
    batch = time_calls({'batch': lambda: arm.ik_batch(T[:n], near[:n])}, repeats=max(3, repeats // 3), warmup=1)['batch']
    rate = n / median(batch)
    _, ok_near, _ = arm.ik_batch(T[:n], near[:n])
    q, ok, reasons = arm.ik_batch(T[:n])
    called_out = sum(r.startswith('out of reach') for r in reasons)
    rows += [
        ['12', f'FR3 IK batched from seeds 5 cm off ({n:,} poses, numeric, compiled)', f'{rate:,.0f} poses/s',
         f'{ok_near.sum()}/{n} solved; ' + _peer_ratio(peer, arm, T, near, median(batch) / n, repeats),
         '≥ 5,000 poses/s', 'met' if rate >= 5000 else 'missed'],
        ['12', 'FR3 IK from the default seed (random reachable poses)', f'{100 * ok.mean():.1f} % solved',
         f'{n - ok.sum()} not found, {called_out} called out of reach', '≥ 99.5 %, none out of reach',
         'met' if ok.mean() >= 0.995 and called_out == 0 else 'missed']]
    return rows


def _cycle_row(repeats):
    times, details = {}, []
    for name in ('picking_arm', 'ur5e', 'fr3'):
        arm = ArmModel.from_urdf(urdf_path(name))
        planner = Planner(arm, PlannerSettings(speed_scale=1.0))
        home = np.asarray(HOMES.get(name, PickSettings().home_positions), float)
        settings = PickSettings(home_positions=tuple(home)).validate(arm)
        start = (home, np.zeros_like(home), np.zeros_like(home))
        times[name] = lambda p=planner, s=settings, st=start: PickCycle(p, s).plan(st, APPLE)
    measured = time_calls(times, repeats=10 * repeats, warmup=3)
    worst = max(median(measured['ur5e']), median(measured['fr3']))
    details = ', '.join(f'{n} {fmt_time(median(t))}' for n, t in measured.items())
    return [['12', 'the Table 1 cycle planned on the UR5e and the FR3 (slower of the two)', fmt_time(worst),
             details, '≤ 50 ms', 'met' if worst <= 50e-3 else 'missed']]


def run(repeats=15):
    rows = _ik_rows('ur5e', repeats) + _ik_rows('fr3', repeats) + _cycle_row(repeats)
    for row in rows:
        print('  ' + ' | '.join(row), flush=True)
    return rows
