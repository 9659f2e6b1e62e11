"""The demo report's side-by-side comparison of the cycle's methods."""

import numpy as np
import pytest
import yaml

from picking_planner.cli.demo_report import compare_methods
from picking_planner.kinematics import pose_matrix
from picking_planner.resources import config_dir


@pytest.fixture(scope='module')
def compared(arm):
    """compare_methods' rows and plans for the configured cycle and the demo's apple."""
    params = {}
    for name in ('planner.yaml', 'pick_cycle.yaml'):
        params.update(yaml.safe_load((config_dir() / name).read_text())['/**/picking_planner']['ros__parameters'])
    apple = pose_matrix([0.70, 0.15, 0.65], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])
    return compare_methods(arm, params, apple)


def test_the_method_comparison_plans_each_cycle_with_its_own_profiles(arm, compared):
    table, plans = compared
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


def test_the_corners_figure_shows_the_tool_at_each_corner_through_and_rounded(arm, compared, tmp_path):
    from picking_planner.analysis import corner_path, pick_corners
    from picking_planner.cli.demo_report import ROUNDED, THROUGH_CORNERS
    from picking_planner.plots import plot_corners

    _, plans = compared
    corners = pick_corners(arm, plans[THROUGH_CORNERS])
    assert [c[0] for c in corners] == ['P1', 'P3', 'P4 in', 'P4 out']
    tracks = {label: {name: corner_path(arm, plans[key], name) for name, _, _ in corners}
              for label, key in (('through', THROUGH_CORNERS), ('rounded', ROUNDED))}
    past = {}
    for name, point, direction in corners:
        assert np.linalg.norm(direction) == pytest.approx(1.0)
        through, rounded = (np.linalg.norm(tracks[k][name] - point, axis=1).min() for k in ('through', 'rounded'))
        assert through < 1e-3 and 1e-5 < rounded < 0.005          # the rounded path passes near, not through
        past[name] = [float(((tracks[k][name] - point) @ direction).max()) for k in ('through', 'rounded')]
    assert past['P3'][1] < past['P3'][0] - 0.01        # leaving the lift early, the tool turns sooner past P3
    png = plot_corners(tmp_path / 'corners.png', corners, tracks, 'corners')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 10_000
