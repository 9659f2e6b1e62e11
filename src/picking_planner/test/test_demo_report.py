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
    rows = {label.split()[0].rstrip(','): (float(t), float(a), float(j)) for label, t, a, j in
            compare_methods(arm, params, apple)}
    assert set(rows) == {'cubic', 'quintic', 'lspb', 'optimal'}
    # Cubic approach segments step the acceleration (a jerk of thousands per 1 ms sample); quintics do not;
    # the jerk-limited cycle keeps the arm's largest jerk limit; LSPB is the quickest.
    assert rows['cubic'][2] > 10 * rows['quintic'][2]
    assert rows['optimal'][2] <= arm.max_jerk.max() * (1 + 1e-6)
    assert rows['lspb'][0] == min(r[0] for r in rows.values())
