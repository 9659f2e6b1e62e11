"""Apples the arm is not picking: found where a link passes one fast, and passed slowly or around."""

import numpy as np
import pytest
from conftest import shipped_harvest, shipped_orchard

from picking_core import approaches
from picking_core.approaches import DETOURS, check
from picking_core.collision import Allowed, CollisionChecker, World
from picking_core.collision.fruit import MARGIN, RADIUS, Neighbours
from picking_core.goals.planning import GoalPlanner
from picking_core.goals.requests import Kind, Target
from picking_core.goals.start import Start
from picking_core.harvest import Harvest
from picking_core.moving_pick import Follow
from picking_core.kinematics.capsules import ArmCapsules
from picking_core.pick_cycle import HOME_POSITIONS, PickCycle

#: m/s: the pass speed these tests plan with (below the shipped 0.9: their figures were found with it).
PASS = 0.8


def _cycle(seed=1, apple_pass_speed=PASS):
    shipped = shipped_harvest(apple_pass_speed=apple_pass_speed)
    orchard = shipped_orchard(12, seed)
    checker = CollisionChecker(ArmCapsules.from_arm(shipped.arm), orchard.scene)
    return PickCycle(shipped.cycle.planner, shipped.cycle.s, checker), orchard


def _fast_in_joint_moves(cycle, plan, neighbours, apple=None, pressing=True, fast=True):
    """The first fast touch (``fast``) or press off a stem (``pressing``, which no slowing helps) in the joint moves
    of ``plan`` (those of ``apple``'s cycle)."""
    prefix = '' if apple is None else f'apple {apple}: '
    labels = [f'{prefix}{label}' for label in DETOURS]
    return approaches._fast_touch(cycle.checker, plan, neighbours, labels, pressing, fast)[0]


def test_a_link_touching_an_apple_counts_only_when_it_moves_faster_than_the_bruising_margin(arm):
    caps = ArmCapsules.from_arm(arm)
    q0 = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])
    tool = caps.segments(q0)[0]
    k = int(np.argmax(np.linalg.norm(tool.mean(axis=1), axis=1)))       # the capsule farthest out
    on_it = tool[k].mean(axis=0)
    t = np.linspace(0.0, 1.0, 101)
    q = q0 + np.outer(t, [0.05, 0, 0, 0, 0, 0])                         # the waist turns slowly
    slow = Neighbours(caps, [on_it], 0.8)
    assert slow.first_fast_touch(t, q) is None
    fast = slow.first_fast_touch(t / 40.0, q)                            # the same way, 40 times faster
    assert fast is not None and fast.speed > slow.speed and fast.apple == 0
    far = Neighbours(caps, [on_it + [0.0, 0.0, 0.5]], 0.8)
    assert far.first_fast_touch(t / 40.0, q) is None
    assert Neighbours(caps, [], 0.8).first_fast_touch(t, q) is None
    assert slow.touching(q[:1]).all() and not slow.touching(q[:1], ignore=[0]).any()
    assert list(slow.touched_at(q[:1])) == [0]


def _finger(neighbours, q):
    """A finger's segment (2, 3) at ``q`` (1, dof or dof + 1) as the neighbours see it, and its radius."""
    k = neighbours.names.index('a finger')
    return neighbours._segments(q)[0, k], neighbours.radii[k]


def test_a_link_pressing_an_apple_down_off_its_stem_counts_at_any_speed_but_where_the_move_rests(arm):
    """A link that reaches into an apple from above drags it off its stem however slowly it moves; the same link
    as deep into its side only pushes it aside (below the bruising speed, harmless)."""
    caps = ArmCapsules.from_arm(arm)
    q0 = np.asarray(HOME_POSITIONS, float)                               # the fingers reach out level
    t = np.linspace(0.0, 1.0, 101)
    q = q0 + np.outer(t, [0.1, 0, 0, 0, 0, 0])                          # the waist turns slowly
    probe = Neighbours(caps, [[0.0, 0.0, 0.0]], 0.8)
    finger, radius = _finger(probe, q[50:51])
    middle = finger.mean(axis=0)
    axis = (finger[1] - finger[0]) / np.linalg.norm(finger[1] - finger[0])
    assert abs(axis[2]) < 0.7                                            # the finger lies across, not upright
    down = np.array([0.0, 0.0, -1.0]) - (-axis[2]) * axis
    down /= np.linalg.norm(down)
    side = np.cross(axis, down)
    deep = radius + RADIUS - 2 * MARGIN                                  # 2 cm into the apple
    below = Neighbours(caps, [middle + deep * down], 0.8)
    beside = Neighbours(caps, [middle + deep * side], 0.8)
    press = below.first_fast_touch(t, q)
    assert press is not None and press.stem and press.speed < 0.8 and press.limit == 0.0
    assert 'off its stem' in str(press)
    assert beside.first_fast_touch(t, q) is None
    assert below.first_fast_touch(t, q, pressing=False) is None          # as slow past it as allowed
    assert below.first_fast_touch(t, q, spare=[0]) is None               # a move's ends cannot help it
    assert below.first_fast_touch(t, np.repeat(q[:1], len(t), axis=0)) is None     # at rest


def test_the_planner_feels_the_fingers_at_their_opening_as_the_world_does(arm):
    caps = ArmCapsules.from_arm(arm)
    q0 = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])
    wide, shut = np.append(q0, 0.09)[None], np.append(q0, 0.0)[None]
    probe = Neighbours(caps, [[0.0, 0.0, 0.0]], 0.8)
    (finger, radius), (closed, _) = _finger(probe, wide), _finger(probe, shut)
    out = finger.mean(axis=0) - closed.mean(axis=0)
    out /= np.linalg.norm(out)                                           # from the grasp point out past the finger
    apple = finger.mean(axis=0) + (radius + RADIUS + MARGIN / 2) * out
    outside = Neighbours(caps, [apple], 0.8)
    assert outside.touching(wide).all() and not outside.touching(shut).any()
    assert outside.touching(q0[None]).all()                              # no opening given: open


def test_a_swaying_apple_is_kept_farther_off_and_passed_slower_by_its_own_sway(arm):
    """A link meets a swaying apple at the sum of their speeds, and as far out as the apple strays."""
    caps = ArmCapsules.from_arm(arm)
    q0 = np.array([0.0, 0.2, 1.6, 0.0, 1.3, 0.0])
    tool = caps.segments(q0)[0]
    k = int(np.argmax(np.linalg.norm(tool.mean(axis=1), axis=1)))
    on_it = tool[k].mean(axis=0)
    t = np.linspace(0.0, 1.0, 101)
    q = q0 + np.outer(t, [0.05, 0, 0, 0, 0, 0])
    speed = Neighbours(caps, [on_it], 1e-6).first_fast_touch(t / 10.0, q).speed     # the link's, where it meets it
    still = Neighbours(caps, [on_it], 1.1 * speed)
    swaying = Neighbours(caps, [on_it], 1.1 * speed, sway=[[0.0, 0.3 * speed]])
    assert still.first_fast_touch(t / 10.0, q) is None
    touch = swaying.first_fast_touch(t / 10.0, q)
    assert touch is not None and touch.limit == pytest.approx(0.8 * speed)
    # Out of reach when still, within it when it strays that far towards the arm.
    axis = tool[k][1] - tool[k][0]
    axis = axis / max(np.linalg.norm(axis), 1e-12)
    across = np.eye(3)[int(np.argmin(np.abs(axis)))]
    across -= (across @ axis) * axis                                     # square to the capsule's axis
    off = on_it + (caps.radius[k] + RADIUS + MARGIN + 0.02) * across / np.linalg.norm(across)
    assert not Neighbours(caps, [off], 1.0).touching(q[:1]).any()
    assert Neighbours(caps, [off], 1.0, sway=[[0.05, 0.0]]).touching(q[:1]).all()


def test_a_joint_move_that_would_pass_a_neighbouring_apple_fast_goes_around_the_apples():
    cycle, orchard = _cycle()
    centres = np.array([T[:3, 3] for T in orchard.apples])
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    target = 7                                   # its transfer passes apple 5 at full speed
    neighbours = Neighbours(cycle.checker.capsules, np.delete(centres, target, axis=0), PASS)
    direct = cycle.plan((home, z, z), orchard.apples[target])
    assert _fast_in_joint_moves(cycle, direct, neighbours) is not None
    around = cycle.plan((home, z, z), orchard.apples[target], neighbours=neighbours)
    assert _fast_in_joint_moves(cycle, around, neighbours) is None
    assert 'waypoint' in around.extra['detours']
    assert check(cycle.checker, around, Allowed(orchard.apples[target][:3, 3], cycle.s.apple_region)) is None
    assert np.allclose(around.trajectory.end_state()[0], direct.trajectory.end_state()[0], atol=1e-9)


def test_a_pick_passes_the_apples_the_world_knows_slowly_but_its_own():
    """A pick goal among the apples the camera sees (the world's ``apples``) plans as a harvest's cycle does; its own
    apple, seen a few millimetres off, is no neighbour."""
    cycle, orchard = _cycle()
    centres = np.array([T[:3, 3] for T in orchard.apples])
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    target = 7                                   # its transfer passes apple 5 at full speed
    world = World(cycle.arm, orchard.scene)
    goals = GoalPlanner(cycle.planner, cycle.s, world)
    start = Start((home, z, z), None, 0.0, 'measured')
    pick = Target(Kind.PICK, (orchard.apples[target],))
    alone = goals.plan(pick, start).plan
    world.replace(apples=centres + [0.003, 0.0, -0.002])
    among = goals.plan(pick, start).plan
    neighbours = Neighbours(cycle.checker.capsules, np.delete(centres, target, axis=0), PASS)
    assert _fast_in_joint_moves(cycle, alone, neighbours) is not None
    assert _fast_in_joint_moves(cycle, among, neighbours) is None
    assert among.duration > alone.duration


def test_a_harvest_passes_the_apples_still_on_the_tree_and_forgets_those_in_the_box():
    cycle, orchard = _cycle()
    harvest = Harvest(cycle)
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    apples = list(orchard.apples)[:6]
    plan = harvest.plan((home, z, z), apples)
    centres = {i: T[:3, 3] for i, T in enumerate(apples)}
    fast = []
    for a in plan.apples:
        centres.pop(a.index)                     # picked in this cycle: no longer a neighbour after
        later = Neighbours(cycle.checker.capsules, list(centres.values()), PASS)
        fast.append(_fast_in_joint_moves(cycle, plan.plan, later, a.index))
    assert len(plan.apples) >= 5
    assert sum(f is not None for f in fast) <= 1, fast


def test_a_harvest_passes_swaying_apples_slower_by_their_sway():
    """Every apple sways ±30 mm at 1 Hz across the approach (a Follow each): the joint moves keep the speed past
    each apple still on the tree below the pass speed less its sway's, counting it as far out as it strays."""
    cycle, orchard = _cycle()
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    apples = list(orchard.apples)

    def swaying(p):
        return Follow(lambda t: (p + [0.0, 0.03 * np.sin(2 * np.pi * t), 0.0], np.eye(3) * 1e-8))
    follows = {i: swaying(T[:3, 3]) for i, T in enumerate(apples)}
    plan = Harvest(cycle).plan((home, z, z), apples, follows=follows, t0=100.0)
    centres = {i: T[:3, 3] for i, T in enumerate(apples)}
    fast = []
    for a in plan.apples:
        centres.pop(a.index)
        sway = [follows[i].reach(c, 100.0) for i, c in centres.items()]
        later = Neighbours(cycle.checker.capsules, list(centres.values()), PASS, sway=sway)
        fast.append(_fast_in_joint_moves(cycle, plan.plan, later, a.index))
    assert len(plan.apples) >= 10
    assert not any(fast), fast                   # (planned as if they hung still, some pass faster)


def test_with_the_pass_speed_off_a_harvest_plans_each_cycle_as_alone():
    off, orchard = _cycle(apple_pass_speed=0.0)
    home, z = np.asarray(off.s.home_positions, float), np.zeros(off.arm.dof)
    apples = list(orchard.apples)[:3]
    first = Harvest(off).plan((home, z, z), apples).apples[0]
    alone = off.plan((home, z, z), apples[first.index], home_after=False)
    assert abs((first.end - first.start) - alone.duration) < 1e-9


def test_a_joint_move_with_no_way_around_the_apples_is_slowed_until_it_passes_them_slowly(monkeypatch):
    cycle, orchard = _cycle()
    monkeypatch.setattr(approaches, '_around_apples', lambda *args, **kwargs: None)
    centres = np.array([T[:3, 3] for T in orchard.apples])
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    target = 7
    neighbours = Neighbours(cycle.checker.capsules, np.delete(centres, target, axis=0), PASS)
    direct = cycle.plan((home, z, z), orchard.apples[target])
    slowed = cycle.plan((home, z, z), orchard.apples[target], neighbours=neighbours)
    assert _fast_in_joint_moves(cycle, slowed, neighbours, pressing=False) is None
    assert '%' in slowed.extra['slowed']
    assert slowed.duration > direct.duration
    allowed = Allowed(orchard.apples[target][:3, 3], cycle.s.apple_region)
    assert check(cycle.checker, slowed, allowed) is None


def test_a_move_pressing_an_apple_with_no_way_clear_of_all_is_slowed_around_the_apple_it_presses(monkeypatch):
    """Seed 3's apple 5: its transfer presses apple 6 off its stem with a finger. With no way clear of every apple,
    the move goes around the apples it would press (touching others) and is slowed past those it passes fast."""
    cycle, orchard = _cycle(3)
    real = approaches._around_apples
    monkeypatch.setattr(approaches, '_around_apples',
                        lambda *args, **kwargs: real(*args, **kwargs) if kwargs.get('fast') is False else None)
    centres = np.array([T[:3, 3] for T in orchard.apples])
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    target = 5
    neighbours = Neighbours(cycle.checker.capsules, np.delete(centres, target, axis=0), PASS)
    direct = cycle.plan((home, z, z), orchard.apples[target])
    press = _fast_in_joint_moves(cycle, direct, neighbours, fast=False)
    assert press is not None and press.stem and press.speed < 1.0
    plan = cycle.plan((home, z, z), orchard.apples[target], neighbours=neighbours)
    assert _fast_in_joint_moves(cycle, plan, neighbours) is None
    assert 'P4 above the box through' in plan.extra['detours'] and 'P4 above the box to' in plan.extra['slowed']
    assert check(cycle.checker, plan, Allowed(orchard.apples[target][:3, 3], cycle.s.apple_region)) is None


def test_a_slowed_move_that_would_cut_into_a_twig_is_taken_around_it_again(monkeypatch):
    # (Seed 2's apple 2: its transfer goes around twig 1 through waypoints and passes apple 6 fast; slowed, the
    # timed move between the same waypoints cuts into the twig.)
    cycle, plan, neighbours, allowed = _without_a_way_around(monkeypatch, seed=2, target=2)
    assert _fast_in_joint_moves(cycle, plan, neighbours, pressing=False) is None
    assert 'P4 above the box' in plan.extra['slowed'] and 'P4 above the box' in plan.extra['detours']
    assert check(cycle.checker, plan, allowed) is None


def _without_a_way_around(monkeypatch, seed=1, target=0, whole=False):
    """The cycle of apple ``target`` of tree ``seed`` with no way around the apples: its moves that pass them fast
    slowed past them (or, ``whole``, all of each); ``(cycle, plan, neighbours, allowed)``."""
    cycle, orchard = _cycle(seed)
    monkeypatch.setattr(approaches, '_around_apples', lambda *args, **kwargs: None)
    if whole:
        monkeypatch.setattr(approaches, '_window', lambda *args: None)
    centres = np.array([T[:3, 3] for T in orchard.apples])
    home, z = np.asarray(cycle.s.home_positions, float), np.zeros(cycle.arm.dof)
    neighbours = Neighbours(cycle.checker.capsules, np.delete(centres, target, axis=0), PASS)
    plan = cycle.plan((home, z, z), orchard.apples[target], neighbours=neighbours)
    return cycle, plan, neighbours, Allowed(orchard.apples[target][:3, 3], cycle.s.apple_region)


def test_a_move_slowed_only_past_the_apples_is_quicker_than_one_slowed_whole(monkeypatch):
    cycle, past, neighbours, allowed = _without_a_way_around(monkeypatch)
    assert 'P4 above the box to' in past.extra['slowed'] and 'P4 above the box' in str(past.extra['slowed'])
    assert 'past the apples' in past.extra['slowed'].split(', ')[0]
    _, whole, _, _ = _without_a_way_around(monkeypatch, whole=True)
    assert 'past the apples' not in whole.extra['slowed']
    for plan in (past, whole):
        assert _fast_in_joint_moves(cycle, plan, neighbours, pressing=False) is None
        assert check(cycle.checker, plan, allowed) is None
    transfer = [next(s for s in plan.segments if s.label == 'P4 above the box').duration for plan in (past, whole)]
    assert transfer[0] < transfer[1]


def test_a_move_slowed_past_the_apples_runs_at_full_speed_once_past_them(monkeypatch):
    cycle, plan, neighbours, _ = _without_a_way_around(monkeypatch)
    seg = next(s for s in plan.segments if s.label == 'P4 above the box')
    t = np.linspace(seg.start, seg.start + seg.duration, 400)
    q, qd = plan.trajectory.sample(t)[:2]
    near = neighbours.touching(q[:, :cycle.arm.dof])
    use = (np.abs(qd[:, :cycle.arm.dof]) / cycle.planner._vmax).max(axis=1)
    assert near.any() and not near[-1]
    # Past the apples the joints keep well below their limits; after them the transfer speeds up again.
    assert use[near].max() < 0.8 and use[t > t[near].max()].max() > 1.5 * use[near].max()


def test_via_points_slowed_leg_by_leg_keep_each_leg_within_its_own_limits(arm):
    from picking_core.planning import Planner, PlannerSettings
    planner = Planner(arm, PlannerSettings(limit_jerk=True, method='optimal', path_method='optimal'))
    qs = np.array([[0.0, 0.2, 1.6, 0.0, -0.2, 0.0], [0.6, 0.0, 1.4, 0.2, 0.0, 0.3],
                   [1.2, -0.2, 1.2, 0.4, 0.2, 0.6], [1.8, -0.4, 1.0, 0.6, 0.4, 0.9]])
    full = planner.via(qs, 'optimal')
    slow = planner.via(qs, 'optimal', scales=(1.0, 0.5, 1.0))
    assert slow.duration > full.duration
    # The slowed leg lies between the points 1 and 2: found where the trajectory passes them.
    t = np.linspace(0.0, slow.duration, 4001)
    q, qd = slow.sample(t)[:2]
    at = [int(np.argmin(np.linalg.norm(q[:, :6] - p, axis=1))) for p in qs[1:3]]
    use = np.abs(qd) / planner._vmax
    assert use[at[0]:at[1] + 1].max() <= 0.5 + 1e-6
    assert use[:at[0]].max() > 0.5 and use[at[1]:].max() > 0.5
    assert np.allclose(slow.end_state()[0], qs[-1])
    for bad in ((1.0, 0.5), (1.0, 0.0, 1.0), (1.0, 1.5, 1.0)):
        with pytest.raises(ValueError):
            planner.via(qs, 'optimal', scales=bad)
    with pytest.raises(ValueError):
        planner.via(qs, 'via_lspb', scales=(1.0, 0.5, 1.0))
