"""Sampling 100 000 time steps x 6 joints: our profiles against roboticstoolbox-python."""

from __future__ import annotations

import numpy as np
from harness import fmt_time, median, p99, time_calls

from picking_core import trajectory

N_STEPS = 100_000
N_JOINTS = 6


def _peer():
    try:
        import roboticstoolbox as rtb
    except ImportError:
        return None
    return rtb


def cases():
    """(name, ours, peer name, peer or None) with identical inputs."""
    rng = np.random.default_rng(7)
    q0 = rng.uniform(-1.0, 1.0, N_JOINTS)
    qf = rng.uniform(-1.0, 1.0, N_JOINTS)
    tf = 3.0
    t = np.linspace(0.0, tf, N_STEPS)
    accel = 1.5 * trajectory.min_lspb_accel(q0, qf, tf).max()
    vias = rng.uniform(-1.0, 1.0, (6, N_JOINTS))
    durations = np.full(5, 2.0)
    t_via = np.linspace(0.0, durations.sum(), N_STEPS)
    rtb = _peer()

    out = [
        ('cubic', lambda: trajectory.cubic(q0, qf, tf).sample(t), None, None),
        ('quintic', lambda: trajectory.quintic(q0, qf, tf).sample(t),
         'jtraj', (lambda: rtb.jtraj(q0, qf, t)) if rtb else None),
        ('lspb', lambda: trajectory.lspb(q0, qf, tf, accel).sample(t),
         'mtraj(trapezoidal)', (lambda: rtb.mtraj(rtb.trapezoidal, q0, qf, t)) if rtb else None),
        ('via_lspb', lambda: trajectory.via_lspb(vias, durations, 40.0).sample(t_via),
         'mstraj', (lambda: rtb.mstraj(vias, dt=durations.sum() / N_STEPS, tacc=0.2,
                                       tsegment=durations)) if rtb else None),
        ('quintic_via', lambda: trajectory.quintic_via(vias, durations).sample(t_via), None, None),
    ]
    return out


GOALS = {'jtraj': 3.0, 'mtraj(trapezoidal)': 10.0, 'mstraj': 10.0}


def write_floor():
    """What every sampler here must at least do: write its q, qd and qdd (3 x N_STEPS x N_JOINTS
    doubles, 14 MB). Timed beside each case, it bounds the ratio a peer can be beaten by."""
    np.empty((3 * N_JOINTS, N_STEPS)).fill(0.5)


def run(repeats=15):
    """Rows of the table (see run.py): our median and p99, the peer side by side, the goal."""
    rows = []
    for name, ours, peer_name, peer in cases():
        fns = {'ours': ours, 'floor': write_floor}
        if peer is not None:
            fns['peer'] = peer
        times = time_calls(fns, repeats=repeats)
        floor = median(times['floor'])
        result = f'{fmt_time(median(times["ours"]))} (p99 {fmt_time(p99(times["ours"]))})'
        goal = f'≥ {GOALS[peer_name]:g}x {peer_name}' if peer_name else '—'
        if peer is not None:
            ratio = median(times['peer']) / median(times['ours'])
            detail = (f'rtb {peer_name} {fmt_time(median(times["peer"]))}: {ratio:.1f}x; writing the output '
                      f'alone {fmt_time(floor)} (at most {median(times["peer"]) / floor:.1f}x)')
            verdict = 'met' if ratio >= GOALS[peer_name] else 'missed'
        else:
            detail = (f'rtb {peer_name}: not installed' if peer_name else '—') + \
                f'; writing the output alone {fmt_time(floor)}'
            verdict = '—'
        rows.append(['1', f'sample {name} ({N_STEPS:,} x {N_JOINTS})', result, detail, goal, verdict])
        print('  ' + ' | '.join(rows[-1]), flush=True)
    return rows
