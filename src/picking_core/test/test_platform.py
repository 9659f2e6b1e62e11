"""Several arms on one tree: the collision capsules, the split, arms kept apart, and a run of the
coordinator with planners simulated by their predicted plans."""

import numpy as np
import pytest
from conftest import URDF, shipped_harvest

from picking_core.coordination import PlatformRun
from picking_core.harvest import synthetic_tree
from picking_core.kinematics import ArmModel
from picking_core.kinematics.capsules import ArmCapsules, capsule_distances, segment_distances
from picking_core.platform import ArmSchedule, Coordinator, Platform, SharePlan
from picking_description import platform_path


def _brute(p0, p1, q0, q1, n=801):
    u = np.linspace(0.0, 1.0, n)[:, None]
    a, b = p0 + u * (p1 - p0), q0 + u * (q1 - q0)
    return np.min(np.linalg.norm(a[:, None] - b[None], axis=2))


def test_segment_distances_match_a_dense_search_including_parallel_and_point_segments():
    rng = np.random.default_rng(1)
    P = rng.normal(size=(300, 4, 3))
    P[0, 1] = P[0, 0]                                  # a point
    P[1] = [[0, 0, 0], [1, 0, 0], [0.3, 0.5, 0], [1.3, 0.5, 0]]   # parallel, side by side
    P[2, 3] = P[2, 2]
    P[2, 1] = P[2, 0]                                  # two points
    d = segment_distances(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    ref = np.array([_brute(*p) for p in P])
    assert np.all(d <= ref + 1e-12)                    # never more than the true distance ...
    assert np.max(ref - d) < 5e-3                      # ... and the grid's resolution from it
    assert d[1] == pytest.approx(0.5)


def test_the_arms_capsules_come_from_the_urdf_and_follow_forward_kinematics(arm):
    caps = ArmCapsules.from_arm(arm)
    assert set(caps.links) >= {'base_link', 'upper_arm_link', 'forearm_link', 'wrist_3_link', 'tool0'}
    q = np.array([0.3, 0.4, 1.2, 0.2, -0.5, 0.7])
    S = caps.segments(q[None])[0]
    tool = caps.links.index('tool0')
    assert np.allclose(S[tool, 0], arm.fk(q)[:3, 3])   # the apple in hand sits at the grasp point
    base = np.eye(4)
    base[:3, 3] = [1.0, 2.0, 0.0]
    assert np.allclose(caps.segments(q[None], base)[0], S + [1.0, 2.0, 0.0])
    # Two arms at the same place overlap; a metre apart sideways they do not.
    d = capsule_distances(S[None], caps.radius, caps.segments(q[None], base)[:1], caps.radius)
    assert d.min() > 0.5


def test_collision_geometry_is_a_known_shape_on_the_arms_chain():
    text = URDF.read_text()
    boxed = text.replace('<cylinder radius="0.045" length="0.40"/></geometry></collision>',
                         '<box size="0.1 0.1 0.4"/></geometry></collision>')
    capsules = ArmCapsules.from_arm(ArmModel(boxed))                 # a box: the capsule that holds it
    k = capsules.links.index('forearm_link')
    assert capsules.radius[k] == pytest.approx(np.hypot(0.05, 0.05))
    coned = text.replace('<cylinder radius="0.045" length="0.40"/></geometry></collision>',
                         '<cone radius="0.1" length="0.4"/></geometry></collision>')
    with pytest.raises(ValueError, match='cylinder, sphere, box or mesh'):
        ArmCapsules.from_arm(ArmModel(coned))
    finger = text.replace('<link name="gripper_finger_link">',
                          '<link name="gripper_finger_link">\n<collision><geometry><sphere radius="0.01"/>'
                          '</geometry></collision>')
    with pytest.raises(ValueError, match='does not move with'):
        ArmCapsules.from_arm(ArmModel(finger))


def test_a_platform_file_names_every_arm_once():
    with pytest.raises(ValueError, match='namespace'):
        Platform.from_dict({'arms': [{'xyz': [0, 0, 0]}]})
    with pytest.raises(ValueError, match='share a namespace'):
        Platform.from_dict({'arms': [{'namespace': 'a'}, {'namespace': '/a'}]})
    with pytest.raises(ValueError, match='no layout'):
        Platform.from_yaml(platform_path(), 'nine')
    p = Platform.from_yaml(platform_path())
    assert [a.namespace for a in p.arms] == ['arm1', 'arm2']


@pytest.fixture(scope='module')
def two():
    return Coordinator.from_platform(Platform.from_yaml(platform_path(), 'two'), shipped_harvest)


def test_every_apple_goes_to_an_arm_that_reaches_it_and_the_shares_balance(two):
    tree = two.platform.tree(24, seed=3)
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.5]                      # beyond every arm
    tree.append(far)
    reach = two.reach(tree)
    shares, skipped = two.split(tree, reach)
    assert [s.index for s in skipped] == [24] and 'no arm' in skipped[0].reason
    for k, share in enumerate(shares):
        assert all(i in reach[k] for i in share)
    assert sorted(shares[0] + shares[1]) == list(range(24))
    assert abs(len(shares[0]) - len(shares[1])) <= 4


@pytest.fixture(scope='module')
def close():
    """Two arms 0.6 m apart and four apples between them: each arm given the two on the other's side."""
    p = Platform.from_dict({'arms': [
        {'namespace': 'a1', 'xyz': [0, -0.3, 0], 'params': {'box_position': [0.05, -0.55, 0.3]}},
        {'namespace': 'a2', 'xyz': [0, 0.3, 0], 'params': {'box_position': [0.05, 0.55, 0.3]}}]})
    tree = synthetic_tree(4, seed=2, low=(0.6, -0.06, 0.6), high=(0.7, 0.06, 0.7), spacing=0.04)
    return Coordinator.from_platform(p, shipped_harvest), tree


def test_plans_that_would_bring_two_arms_closer_than_the_clearance_are_kept_apart(close):
    c, tree = close
    shares = [[0, 1], [2, 3]]
    starts = [(h.home, np.zeros(6), np.zeros(6)) for h in c.harvests]
    naive = [ArmSchedule(c.platform.arms[k], s, c._plan(k, s, tree, starts[k])) for k, s in enumerate(shares)]
    _, conflicts = c.closest(naive)
    assert conflicts, 'the case must conflict as planned'
    s = c.schedule(tree, shares=shares)
    assert s.decisions and all('within' in d for d in s.decisions)
    assert s.closest.distance >= c.clearance
    assert not c.closest(s.arms)[1]
    assert s.picked() == 4
    # The arm that yielded waits (or gave its apple away): the two never work side by side.
    assert any(a.start > 0 for a in s.arms) or any('went from' in d for d in s.decisions)


def test_the_slack_keeps_arms_apart_for_a_start_a_little_off(close):
    c, tree = close
    s = c.schedule(tree, shares=[[0, 1], [2, 3]])
    for shift in (-c.slack, c.slack):
        moved = [ArmSchedule(a.mount, a.apples, a.plan, a.start + (shift if k else 0.0))
                 for k, a in enumerate(s.arms)]
        assert c.closest(moved)[0].distance >= c.clearance - 1e-9


def test_a_share_sent_in_parts_runs_on_from_where_each_part_leaves_the_arm(two):
    c = Coordinator(two.platform, two.harvests, chunk=2)
    tree = two.platform.tree(10, seed=5)
    h = c.harvests[0]
    share = c._plan(0, list(range(10)), tree, (h.home, np.zeros(6), np.zeros(6)))
    assert isinstance(share, SharePlan) and len(share.chunks) >= 2
    for (_, before, off0), (_, after, off1) in zip(share.chunks, share.chunks[1:]):
        # The next part starts at rest in the box, where the last apple of the one before was dropped.
        end = before.plan.trajectory.state_at(before.apples[-1].end)
        assert off1 == pytest.approx(off0 + before.apples[-1].end)
        assert np.allclose(after.plan.trajectory.state_at(0.0)[0], end[0], atol=1e-9)
        assert np.allclose(end[1], 0.0, atol=1e-9)
    times = np.array([a.start for a in share.apples])
    assert np.all(np.diff(times) > 0)


class FakePlanners:
    """Each arm's planner as the coordinator predicts it: a part sent is released as planned, its
    apples reported in the box at their times, replaced or ended; ``fail`` = {arm: time} aborts an arm."""

    def __init__(self, run, fail=None):
        self.run, self.fail, self.parts, self.t = run, dict(fail or {}), {}, [0.0]

    def step(self, dt=0.05):
        run, now = self.run, self.t[0]
        for k, share in run.due():
            a = run.arms[k]
            n = a.sent_parts - 1
            key = f'{k}.{n}.{now}'
            run.sent(k, key, [i for i, _ in share])
            ids, hp, off = a.share.chunks[n]
            start = now + a.lead if n == 0 else a.start + off
            traj = hp.plan.trajectory
            ts = np.arange(0.0, traj.duration, 0.01)
            run.on_released(k, start, ts, traj.sample(ts)[0])
            self.parts.setdefault(k, []).append([key, start, hp, 0, n, ids])
        for k, parts in self.parts.items():
            for item in list(parts):
                key, start, hp, m, n, ids = item
                if k in self.fail and now >= self.fail[k]:
                    run.on_status(k, {'goal': key, 'state': 'aborted'}, 'aborted: feedback lost')
                    parts.remove(item)
                    continue
                while m < len(hp.apples) and start + hp.apples[m].end <= now:
                    run.on_status(k, {'goal': key, 'apple': str(ids.index(hp.apples[m].index)),
                                      'apple_state': 'picked'}, 'picked')
                    m += 1
                item[3] = m
                later = any(o[4] > n for o in parts)
                if later and m == len(hp.apples):
                    run.on_status(k, {'goal': key, 'state': 'superseded'}, 'superseded')
                    parts.remove(item)
                elif not later and now >= start + hp.plan.duration:
                    run.on_status(k, {'goal': key, 'state': 'succeeded'}, 'done')
                    parts.remove(item)
        for k in list(self.fail):
            if now >= self.fail[k]:
                del self.fail[k]
        for k, a in enumerate(run.arms):
            if a.released.parts:
                run.on_joint_state(k, a.released.q(now)[0])
        self.t[0] += dt

    def until_done(self, limit=400.0):
        while not self.run.finished() and self.t[0] < limit:
            self.step()
        return self.run


def test_a_run_sends_every_arm_its_share_in_parts_and_ends_with_every_apple_in_a_box(two):
    c = Coordinator(two.platform, two.harvests, chunk=3)
    tree = two.platform.tree(10, seed=1)
    clock = [0.0]
    run = PlatformRun(c, tree, lambda: clock[0])
    fake = FakePlanners(run)
    fake.t = clock
    fake.until_done()
    assert run.finished() and run.picked() == 10 and not run.skipped
    assert run.measured.distance >= c.clearance
    s = run.summary()
    assert sum(v['picked'] for v in s['arms'].values()) == 10
    assert s['apples_per_hour'] > 0 and 'apples/h' in run.words()
    assert all(v['picked'] > 0 for v in s['arms'].values())


def test_an_arm_that_fails_gives_its_apples_back_and_the_other_arms_pick_them(two):
    c = Coordinator(two.platform, two.harvests, chunk=3)
    tree = two.platform.tree(8, seed=1)
    clock = [0.0]
    run = PlatformRun(c, tree, lambda: clock[0])
    fake = FakePlanners(run, fail={0: 12.0})
    fake.t = clock
    fake.until_done()
    assert run.finished()
    assert any('aborted' in w for _, w in run.events) or run.rounds >= 2
    assert run.rounds >= 2
    assert run.picked() + len(run.skipped) == 8
    assert run.picked() >= 6


def test_a_round_no_schedule_keeps_apart_leaves_its_apples_on_the_tree_and_the_run_ends(two, monkeypatch):
    c = Coordinator(two.platform, two.harvests, chunk=3)
    tree = two.platform.tree(6, seed=1)
    clock = [0.0]

    def conflict(*args, **kwargs):
        raise RuntimeError('arms still conflict after 1 decisions: 4.9 cm between arm1 and arm2')
    monkeypatch.setattr(c, 'schedule', conflict)
    run = PlatformRun(c, tree, lambda: clock[0])
    fake = FakePlanners(run)
    fake.t = clock
    fake.until_done(limit=20.0)
    assert run.finished() and run.picked() == 0 and len(run.skipped) == 6
    assert any(level == 'WARN' and 'no schedule kept the arms apart' in w for level, w in run.events)


def test_a_released_plan_that_comes_too_close_to_another_arms_stops_its_arm(close):
    c, tree = close
    clock = [0.0]
    run = PlatformRun(c, tree, lambda: clock[0])
    run.due()
    s = c.schedule(tree, shares=[[0, 1], [2, 3]])
    naive = [c._plan(k, share, tree, (c.harvests[k].home, np.zeros(6), np.zeros(6)))
             for k, share in enumerate([[0, 1], [2, 3]])]
    assert s.decisions
    for k in (0, 1):
        run.arms[k].state = 'harvesting'
        traj = naive[k].chunks[0][1].plan.trajectory
        ts = np.arange(0.0, traj.duration, 0.01)
        run.on_released(k, 5.0, ts, traj.sample(ts)[0])       # both at once: as they were before kept apart
    assert [k for k, _ in run.to_stop] == [1]
    assert 'within' in run.to_stop[0][1] and run.stops == 1
