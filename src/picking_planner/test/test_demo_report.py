"""The demo report's side-by-side comparison of the cycle's methods."""

import numpy as np
import yaml

from picking_planner.cli.demo_report import compare_methods
from picking_planner.kinematics import pose_matrix
from picking_planner.resources import config_dir


def test_the_method_comparison_plans_each_cycle_with_its_own_profiles(arm):
    params = {}
    for name in ('planner.yaml', 'pick_cycle.yaml'):
        params.update(yaml.safe_load((config_dir() / name).read_text())['/**/picking_planner']['ros__parameters'])
    apple = pose_matrix([0.70, 0.15, 0.65], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])
    table, plans = compare_methods(arm, params, apple)
    rows = {label: (float(t), float(a), float(j)) for label, t, a, j in table}
    assert {label: f'{plan.duration:.2f}' for label, plan in plans.items()} == {r[0]: r[1] for r in table}
    cubic, quintic, lspb, optimal, rounded = (rows[next(label for label in rows if label.startswith(start))]
                                              for start in ('cubic', 'quintic', 'lspb', 'optimal', 'the same'))
    assert len(rows) == 5 and 'corners rounded' in next(reversed(rows))
    # Cubic approach segments step the acceleration (a jerk of thousands per 1 ms sample); quintics do not;
    # the jerk-limited cycles keep the arm's largest jerk limit, the one with rounded corners is quicker;
    # LSPB is the quickest.
    assert cubic[2] > 10 * quintic[2]
    assert max(optimal[2], rounded[2]) <= arm.max_jerk.max() * (1 + 1e-6)
    assert rounded[0] < optimal[0] - 0.1
    assert lspb[0] == min(r[0] for r in rows.values())
