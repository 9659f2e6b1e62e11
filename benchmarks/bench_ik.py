"""Inverse kinematics: one pose at a time and batched, against roboticstoolbox's Puma560."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness import fmt_time, median, p99, time_calls
from picking_planner.kinematics import ArmModel

CONFIG = Path(__file__).resolve().parents[1] / 'config'
N_SINGLE = 200
N_BATCH = 10_000


def _puma():
    try:
        import roboticstoolbox as rtb
    except ImportError:
        return None
    return rtb.models.DH.Puma560()


def run(repeats=15):
    arm = ArmModel.from_urdf(CONFIG / 'picking_arm.urdf')
    rng = np.random.default_rng(11)
    Q = rng.uniform(arm.lower, arm.upper, (N_BATCH, arm.dof))
    T = arm.fk(Q)
    seeds = Q[:N_SINGLE]

    def ours_single():
        for i in range(N_SINGLE):
            try:
                arm.ik(T[i], seeds[i])
            except ValueError:
                pass

    fns = {'ours': ours_single}
    puma = _puma()
    if puma is not None:
        qp = rng.uniform(-1.0, 1.0, (N_SINGLE, 6)) * 0.8
        Tp = [puma.fkine(q) for q in qp]
        fns['ikine_a'] = lambda: [puma.ikine_a(t) for t in Tp]
        fns['ikine_LM'] = lambda: [puma.ikine_LM(t, q0=q) for t, q in zip(Tp, qp)]
    times = time_calls(fns, repeats=max(3, repeats // 3), warmup=1)
    per = {k: v / N_SINGLE for k, v in times.items()}
    rows = []
    for peer in ('ikine_a', 'ikine_LM'):
        row = ['IK one pose (6R, closed form)', fmt_time(median(per['ours'])), fmt_time(p99(per['ours']))]
        if peer in per:
            row += [f'rtb Puma560 {peer}', fmt_time(median(per[peer])),
                    f'{median(per[peer]) / median(per["ours"]):.1f}x']
        else:
            row += [f'rtb {peer}: not installed', '—', '—']
        rows.append(row)
    batch = time_calls({'batch': lambda: arm.ik_batch(T, Q)}, repeats=repeats)['batch']
    rows.append([f'IK batched ({N_BATCH:,} poses)', f'{N_BATCH / median(batch):,.0f} poses/s',
                 f'{N_BATCH / p99(batch):,.0f} poses/s', '—', '—', '—'])
    for row in rows:
        print('  ' + ' | '.join(row), flush=True)
    return rows
