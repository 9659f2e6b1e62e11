"""Inverse kinematics: one pose at a time and batched, against roboticstoolbox's Puma560."""

from __future__ import annotations

import numpy as np
from harness import fmt_time, median, p99, time_calls

from picking_core.kinematics import ArmModel
from picking_description import default_urdf

N_SINGLE = 200
N_BATCH = 10_000


def _puma():
    try:
        import roboticstoolbox as rtb
    except ImportError:
        return None
    return rtb.models.DH.Puma560()


def run(repeats=15):
    arm = ArmModel.from_urdf(default_urdf())
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
    ours = median(per['ours'])
    rows = []
    result = f'{fmt_time(ours)} per pose (p99 {fmt_time(p99(per["ours"]))})'
    for peer, goal in (('ikine_a', 10.0), ('ikine_LM', None)):
        if peer in per:
            ratio = median(per[peer]) / ours
            detail = f'rtb Puma560 {peer} {fmt_time(median(per[peer]))}: {ratio:.1f}x'
            verdict = ('met' if ratio >= goal else 'missed') if goal else '—'
        else:
            detail, verdict = f'rtb {peer}: not installed', '—'
        rows.append(['1', 'IK one pose (6R, closed form, compiled)', result, detail,
                     f'≥ {goal:g}x {peer}' if goal else '—', verdict])
    rows.append(['1', 'IK one pose, absolute (issue 3)', fmt_time(ours), '—', '≤ 25 µs',
                 'met' if ours <= 25e-6 else 'missed'])
    batch = time_calls({'batch': lambda: arm.ik_batch(T, Q)}, repeats=repeats)['batch']
    rate = N_BATCH / median(batch)
    rows.append(['1', f'IK batched ({N_BATCH:,} poses)', f'{rate:,.0f} poses/s',
                 f'p99 {N_BATCH / p99(batch):,.0f} poses/s', '≥ 200,000 poses/s',
                 'met' if rate >= 200_000 else 'missed'])
    for row in rows:
        print('  ' + ' | '.join(row), flush=True)
    return rows
