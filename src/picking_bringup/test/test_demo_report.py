"""The demo report's side-by-side comparison of the cycle's methods."""

import numpy as np
import pytest
import yaml

from picking_bringup.demo_report import compare_methods
from picking_bringup.shipped import config_dir, shipped_harvest
from picking_core.kinematics import pose_matrix
from picking_description import platform_path


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
    # LSPB is the quickest of the paper's profiles.
    assert cubic[2] > 10 * quintic[2]
    assert max(optimal[2], rounded[2]) <= arm.max_jerk.max() * (1 + 1e-6)
    assert rounded[0] < optimal[0] - 0.1
    assert lspb[0] < min(cubic[0], quintic[0])


def test_the_corners_figure_shows_the_tool_at_each_corner_through_and_rounded(arm, compared, tmp_path):
    from picking_bringup.demo_report import BOX_ROUND_RADIUS, ROUNDED, THROUGH_CORNERS
    from picking_bringup.plots import plot_corners
    from picking_core.analysis import corner_path, pick_corners

    _, plans = compared
    corners = pick_corners(arm, plans[THROUGH_CORNERS])
    assert [c[0] for c in corners] == ['P1', 'P3', 'P4 in', 'P4 out']
    tracks = {label: {name: corner_path(arm, plans[key], name) for name, _, _ in corners}
              for label, key in (('through', THROUGH_CORNERS), ('rounded', ROUNDED))}
    past = {}
    for name, point, direction in corners:
        assert np.linalg.norm(direction) == pytest.approx(1.0)
        through, rounded = (np.linalg.norm(tracks[k][name] - point, axis=1).min() for k in ('through', 'rounded'))
        # The rounded path passes near, not through (over the box it descends during the swing).
        assert through < 1e-3 and 1e-5 < rounded < (0.005 if name in ('P1', 'P3') else BOX_ROUND_RADIUS)
        past[name] = [float(((tracks[k][name] - point) @ direction).max()) for k in ('through', 'rounded')]
    assert past['P3'][1] < past['P3'][0] - 0.01        # leaving the lift early, the tool turns sooner past P3
    png = plot_corners(tmp_path / 'corners.png', corners, tracks, 'corners')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 10_000


def test_the_harvest_section_reads_each_apple_from_the_statuses_and_draws_the_tree(tmp_path):
    """Scenario 3 as the planner reports it: the apples in picking order, the skips with their reasons,
    the markers of the tree and its plot."""
    from std_msgs.msg import Header

    from picking_bringup.demo_report import harvest_markers, harvest_statuses, on_the_tree
    from picking_bringup.plots import plot_harvest
    from picking_common.status import status
    from picking_core.harvest import synthetic_tree

    said = [status('p', 'OK', 'harvest goal 7.0: accepted', goal='7.0', kind='harvest', state='accepted',
                   order_estimate=3.0, given_order_estimate=3.5),
            status('p', 'WARN', 'harvest goal 7.0: apple 1 skipped: unreachable: P1 (approach)', goal='7.0',
                   apple=1, apple_state='skipped'),
            status('p', 'OK', 'harvest goal 7.0: apple 2 picked: in the box (1 of 2)', goal='7.0', apple=2,
                   apple_state='picked', at=4.0),
            status('p', 'OK', 'another goal', goal='8.0', apple=5, apple_state='picked', at=1.0),
            status('p', 'OK', 'harvest goal 7.0: apple 0 picked: in the box (2 of 2)', goal='7.0', apple=0,
                   apple_state='picked', at=8.0),
            status('p', 'OK', 'harvest goal succeeded', goal='7.0', state='succeeded', picked=2)]

    class Rec:
        def messages(self, topic):
            return [(0.0, m) for m in said] if topic == 'planner_status' else []
    got = harvest_statuses(Rec(), '7.0')
    assert got['picked'] == [(2, 4.0), (0, 8.0)]
    assert got['skipped'] == [(1, 'unreachable: P1 (approach)')]
    assert got['accepted']['order_estimate'] == '3' and got['final']['picked'] == '2'
    apples = synthetic_tree(3, seed=2)
    assert on_the_tree(got, apples)['picked'] == [(2, 4.0), (0, 8.0)]       # no places said: as numbered
    markers = harvest_markers(apples, got, Header(frame_id='base_link')).markers
    texts = {m.id: m.text for m in markers if m.ns == 'order'}
    assert texts == {0: '2', 1: 'skipped', 2: '1'}
    order = next(m for m in markers if m.ns == 'visiting order')
    assert [p.x for p in order.points] == [apples[2][0, 3], apples[0][0, 3]]
    tool = np.array([T[:3, 3] for T in apples])
    assert plot_harvest(tmp_path / 'h.png', apples, [2, 0], [1], tool, 'a tree').stat().st_size > 10_000


def test_a_harvest_from_the_camera_is_read_against_the_tree_by_place():
    """The planner numbers the apples its camera saw; the report matches each to the tree's apple where it is (a
    few millimetres off), and names an apple that is none of the tree's."""
    from picking_bringup.demo_report import on_the_tree
    from picking_core.harvest import synthetic_tree
    tree = synthetic_tree(4, seed=3)
    near = {k: tuple(tree[i][:3, 3] + 0.004) for k, i in ((0, 3), (1, 0))}
    near[3] = tuple(tree[2][:3, 3] - 0.004)
    said = {'picked': [(0, 4.0), (1, 8.0), (2, 9.0)], 'missed': [(3, 'the gripper held nothing')], 'skipped': [],
            'accepted': {}, 'final': {}, 'places': {**near, 2: (9.0, 9.0, 9.0)}}
    got = on_the_tree(said, tree)
    assert got['picked'] == [(3, 4.0), (0, 8.0)] and got['unmatched'] == [2]
    assert [(word, place) for word, place, _, _ in got['astray']] == [('picked', (9.0, 9.0, 9.0))]
    assert got['astray'][0][2] == pytest.approx(min(np.linalg.norm(T[:3, 3] - 9.0) for T in tree))
    assert got['missed'] == [(2, 'the gripper held nothing')]
    assert sorted(got['places']) == [0, 2, 3]


def test_the_platform_figure_draws_each_arms_apples_path_and_links(tmp_path):
    from picking_bringup.demo_platform import _grasp_drawings
    from picking_bringup.plots import plot_platform
    from picking_core.platform import Coordinator, Platform
    platform = Platform.from_yaml(platform_path(), 'two')
    coordinator = Coordinator.from_platform(platform, shipped_harvest)
    tree = platform.tree(6, seed=1)
    by_arm = {'arm1': [i for i, T in enumerate(tree) if T[1, 3] < 0], 'arm2': [i for i, T in enumerate(tree) if T[1, 3] >= 0]}
    drawn = _grasp_drawings(coordinator, tree, by_arm)
    assert len(drawn) == 4 and all(points.shape == (8, 3) for _, points in drawn)
    # The links end at the apple: the last joint origin is the grasp point.
    first = by_arm['arm1'][0]
    assert np.allclose(drawn[0][1][-1], tree[first][:3, 3], atol=1e-6)
    tools = {ns: np.array([T[:3, 3] for T in tree]) for ns in by_arm}
    path = plot_platform(tmp_path / 'platform.png', tree, by_arm, [], tools,
                         [m.base[:3, 3] for m in platform.arms], drawn, 'two arms')
    assert path.stat().st_size > 10_000


def test_the_wind_scenarios_plot_draws_each_pick_within_the_sways_band(tmp_path):
    from picking_bringup.plots import plot_sway_picks
    t = np.linspace(-1.2, 0.3, 16)
    picks = [(f'apple {i}: {label}', t, 30 * np.sin(2 * np.pi * t), t, np.full_like(t, -400.0 + 10 * i), 0.0)
             for i, label in enumerate(('1.0 mm off centre', 'closed beside it'))]
    path = plot_sway_picks(tmp_path / 'wind.png', picks, 'swaying apples')
    assert path.stat().st_size > 10_000
