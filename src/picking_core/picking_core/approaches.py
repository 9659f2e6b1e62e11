"""Picking around branches: when the requested approach is blocked, other IK branches, then other
directions within a cone (pure core of the pick cycle's search).

A blocked or unreachable approach is not a refused apple. The requested grasp is tried on the arm's
other IK branches (elbow, shoulder or wrist the other way: a line that would jump on one branch, or an
elbow in a branch, may be clear on another): first when it failed kinematically, last when it was
blocked. The grasp axis (the tool's z, into the apple) is tilted by up to ``approach_cone`` in every
direction around it, and the gripper rolled about it; each candidate is first screened cheaply (its
approach and lift lines by IK every centimetre, checked for collisions and joint jumps), and only the
candidates that pass are planned as whole cycles and checked densely. The quickest clear cycle among
the first few wins. Only when every grasp is blocked are they tried again with the other ways out with
the apple (straight back along the approach, an arc up and back, straight up: a twig just above an apple
blocks the lift, not the way in; an arc is screened along its chord). An apple with none is refused with
the obstacle that blocked most candidates.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from .collision import Allowed
from .kinematics import Unreachable
from .planning.joint_path import REFINE, NoPath, doubled, rrt_connect

#: The joint moves of the cycle that may go around an obstacle (pick_cycle.DETOURS).
DETOURS = ('P0 home', 'P1 approach', 'P4 above the box', 'P0 back home')
#: Points a joint move is held to the straight way by, when that way passes the apples and the timed move not.
STRAIGHT = 3
#: Extensions of the joint path tried around the apples (a cheap look: a move without one is slowed instead).
PAST_APPLES_TRIES = 150
#: The slowest a joint move is made to pass apples (a fraction of the planner's speed), and the margin below the
#: pass speed each slowing aims at (link speeds scale with the move's).
MIN_SLOW, SLOW_MARGIN = 0.3, 0.9
#: s: a move slowed past apples is slowed from this long before it comes within reach of them to this long after.
WINDOW_PAD = 0.1
#: rad: the tilts tried, in steps up to the cone.
TILT_STEP = np.radians(15.0)
#: The ways out with the apple tried for a blocked one, after every grasp with the settings' lift (the pick
#: cycle's LIFT_METHODS, in this order), and how they are said.
LIFTS = ('back', 'arc', 'line')
LIFT_WORDS = {'back': 'straight back', 'arc': 'up and back along an arc', 'line': 'straight up'}
#: Directions of tilt around the grasp axis.
AZIMUTHS = 8
#: rad: the gripper's rolls about the tilted axis (the fingers' plane turned).
ROLLS = np.radians([0.0, 60.0, -60.0])
#: Screened candidates planned as whole cycles; the quickest clear one of them is taken.
MAX_CYCLES = 4
#: Blocked candidates whose obstacle is named (the one that blocked most is given in a refusal).
NAMED = 12
#: m between the IK points of a screened line.
SCREEN_STEP = 0.01
#: rad: a joint moving further between two screened points breaks the line (another IK branch).
SCREEN_JUMP = 0.3
#: Candidates whose lines are checked for collisions at once, quickest first (a batch amortises the checker's
#: numpy calls; stopping once enough have passed skips the rest).
SCREEN_BATCH = 12
#: Every this many points of the screened lines (SCREEN_STEP apart) are checked first.
SCREEN_COARSE = 4


class Blocked(Unreachable):
    """No clear cycle: the reason names the obstacle, where and when (a refused apple, as Unreachable)."""


class BrakeBlocked(Blocked):
    """The arm would hit something while it brakes from where the plan starts, before any way around."""


@dataclass(frozen=True)
class Approach:
    """A grasp pose tried: ``tilt`` of its axis from the requested one and ``roll`` about it (rad);
    ``branch``: the joints at P1 (the start of the line to the apple), None for the IK solution
    nearest home; ``lift``: the way out with the apple (one of the pick cycle's LIFT_METHODS), None for
    the settings'."""

    pose: np.ndarray
    tilt: float
    roll: float
    branch: np.ndarray | None = None
    lift: str | None = None

    def words(self):
        out = (f'{np.degrees(self.tilt):.0f}° off the requested axis, rolled {np.degrees(self.roll):+.0f}°'
               if self.branch is None else 'as requested on another IK branch of the arm')
        return f'approached {out}' + ('' if self.lift is None else f', lifted out {LIFT_WORDS[self.lift]}')


def other_branches(cycle, approach):
    """``approach`` reached on each other IK branch at its P1 within the joint limits (the one nearest
    home is the default), the nearest home first."""
    arm = cycle.arm
    P1 = cycle.key_poses(approach.pose, approach.lift)['P1']
    home = np.asarray(cycle.s.home_positions, float)
    try:
        default = arm.check_reachable(P1, seed=home)
    except Unreachable:
        return []
    sols = [q for q in arm.ik_all(P1) if arm.within_limits(q) and np.abs(q - default).max() > 1e-6]
    sols.sort(key=lambda q: float(np.abs(q - home).max()))
    return [replace(approach, branch=q) for q in sols]


def candidates(T, cone):
    """The grasp poses to try for an apple at ``T`` (4x4): the requested one first, then every tilt
    (within ``cone``, rad), direction and roll, the least changed first."""
    T = np.asarray(T, float)
    tilts = np.arange(TILT_STEP, cone + 1e-9, TILT_STEP) if cone > 0 else np.zeros(0)
    # (tilt, azimuth, roll) of each candidate after the requested pose: its rolls, then each tilt's
    # directions and rolls.
    turns = [(0.0, 0.0, roll) for roll in ROLLS[1:]]
    turns += [(tilt, 2 * np.pi * k / AZIMUTHS, roll) for tilt in tilts for roll in ROLLS for k in range(AZIMUTHS)]
    out = [Approach(T, 0.0, 0.0)]
    if turns:
        tilt, azimuth, roll = np.array(turns).T
        # Tilting about the axis (-sin, cos, 0) of the grasp frame moves its z toward the azimuth; then the roll.
        axis = np.stack([-np.sin(azimuth), np.cos(azimuth), np.zeros_like(azimuth)], axis=1)
        R = (Rotation.from_rotvec(tilt[:, None] * axis)
             * Rotation.from_rotvec(np.outer(roll, [0.0, 0.0, 1.0]))).as_matrix()
        poses = np.repeat(T[None], len(turns), axis=0)
        poses[:, :3, :3] = T[:3, :3] @ R
        out += [Approach(P, float(t), float(r)) for P, t, r in zip(poses, tilt, roll)]
    return out


def clear_cycle(cycle, plan_one, T_apple, neighbours=None):
    """The quickest clear cycle for the apple at ``T_apple``: ``plan_one(T, detours, branch, slow, lift)`` plans
    the cycle for a grasp pose (``branch``: the joints at its P1, None for the default; ``slow``: joint moves
    slowed, see :meth:`~picking_core.pick_cycle.PickCycle._plan`; ``lift``: the way out, None for the
    settings'); ``cycle``
    (:class:`~picking_core.pick_cycle.PickCycle`) gives the settings, the arm and the checker;
    ``neighbours``: the apples not picked, passed slowly (:func:`clear_plan`).
    Raises :class:`Blocked` (or Unreachable) with the reason."""
    s, checker = cycle.s, cycle.checker
    allowed = Allowed(np.asarray(T_apple, float)[:3, 3], s.apple_region)
    requested = candidates(T_apple, 0.0)[0]
    # Screened first, with a checker: a requested approach whose lines hit something is not planned in full
    # (and what it hits is looked up only for a refusal's words).
    hit = screen(cycle, [requested], allowed)[1] if checker is not None else []
    first = None                                  # why the requested approach failed, unless it hit something
    if not hit:
        try:
            plan, contact = clear_plan(cycle, lambda detours=None, slow=None: plan_one(T_apple, detours, slow=slow),
                                       allowed, neighbours)
            if contact is None:
                return plan
            first = Blocked(f'the requested approach hits {contact}')
        except Unreachable as exc:
            first = exc
    # The requested grasp on the arm's other IK branches and (with a cone) other grasps: the branches first
    # when the grasp failed kinematically (it is reachable as asked), else the cone's nearby grasps first
    # (another branch swings the arm far round: a longer cycle).
    blockers, screened_out = Counter(), []
    tries = [other_branches(cycle, requested)]
    if s.approach_cone > 0.0:
        kinematic = first is not None and not isinstance(first, Blocked)
        tries.insert(len(tries) if kinematic else 0, candidates(T_apple, s.approach_cone)[1:])
    # Last, the other ways out with the apple, for every grasp: a twig above it blocks the lift, not the approach.
    grasps = candidates(T_apple, s.approach_cone) if s.approach_cone > 0.0 else [requested]
    tries += [[replace(a, lift=lift) for a in grasps] for lift in LIFTS if lift != s.lift_method]
    for approaches in tries:
        passed, blocked = screen(cycle, approaches, allowed, enough=MAX_CYCLES)
        screened_out += blocked
        for approach in passed[:MAX_CYCLES]:
            def make(detours=None, slow=None, a=approach):
                return plan_one(a.pose, detours, a.branch, slow, a.lift)
            try:
                plan, contact = clear_plan(cycle, make, allowed, neighbours)
            except Unreachable:
                continue
            if contact is None:
                plan.extra.update(approach=approach.words(), approach_tilt=approach.tilt,
                                  approach_roll=approach.roll)
                return plan
            blockers[contact.obstacle] += 1
    within = f'within {np.degrees(s.approach_cone):.0f}°' if s.approach_cone > 0.0 else 'on any IK branch'
    if first is None:
        contact = _named(checker, hit, allowed)[1]
        first = Blocked(f'the requested approach hits {contact}' if contact else 'the requested approach is blocked')
    blockers.update(_named(checker, screened_out, allowed)[0])
    if blockers:
        name, _ = blockers.most_common(1)[0]
        raise Blocked(f'{name} blocks every approach {within} ({first})')
    if s.approach_cone <= 0.0:
        raise first
    raise Unreachable(f'{first}; no other approach {within} reaches it either') from None


def clear_plan(cycle, make, allowed, neighbours=None):
    """``(plan, contact)``: ``make(detours)``'s plan (``make(detours, slow)`` when moves are slowed) and its first
    contact (None: clear). A joint move that hits something (one of the cycle's DETOURS) goes around it
    (:func:`_detoured`). With
    ``neighbours`` (:class:`~picking_core.collision.fruit.Neighbours`, the apples not being picked), a
    clear plan's joint moves that pass an apple too fast go around the apples too (:func:`_past_apples`)."""
    if cycle.checker is None:
        return make(), None
    plan, detours, contact = _detoured(cycle, make, allowed)
    if contact is None and neighbours is not None and len(neighbours):
        plan, detours = _past_apples(cycle, make, plan, detours, allowed, neighbours)
    if contact is None and detours:
        plan.extra['detours'] = ', '.join(f'{label} through {len(w)} waypoint{"s" * (len(w) != 1)}'
                                          for label, w in detours.items())
    return plan, contact


def _detoured(cycle, make, allowed, detours=None, slow=None):
    """``(plan, detours, contact)``: ``make(detours, slow)``'s plan, each joint move of it that hits something (one
    of the cycle's DETOURS) taken around it through the waypoints of a collision-free joint path (RRT-Connect,
    shortcut; twice as many of them while the timed move still cuts a corner into it, up to REFINE times; a move
    already given waypoints gets new ones: slowed, its timed path between them differs), at most once a move; the
    first contact left (None: clear)."""
    checker, detours = cycle.checker, dict(detours or {})

    def made():
        return make(detours) if slow is None else make(detours, slow)
    plan = made()
    contact = check(checker, plan, allowed)
    redone = set()
    while contact is not None and contact.part in DETOURS and contact.part not in redone:
        redone.add(contact.part)
        seg = next(x for x in plan.segments if x.label == contact.part)
        ends = np.asarray(plan.trajectory.sample([seg.start, seg.start + seg.duration])[0])[:, :cycle.arm.dof]
        try:
            path = rrt_connect(lambda q: checker.colliding(q, allowed), ends[0], ends[1], cycle.arm.lower,
                               cycle.arm.upper)
        except NoPath:
            break
        if len(path) <= 2:                           # the straight way is clear: the timed move is not
            break
        part = contact.part
        for _ in range(REFINE + 1):
            detours[part] = list(path[1:-1])
            plan = made()
            contact = check(checker, plan, allowed)
            if contact is None or contact.part != part:
                break
            path = doubled(path)                     # the timed move cut a corner of the path: held closer to it
    return plan, detours, contact


@dataclass(frozen=True)
class Slowed:
    """A joint move slowed to ``fraction`` of the planner's speed past apples: only between the configurations
    ``window`` ``(first, last)`` it passes through (None: its own start or end), or the whole move (``window``
    None)."""

    fraction: float
    window: tuple | None = None

    def __str__(self):
        return f'{self.fraction:.0%}' + ('' if self.window is None else ' past the apples')


def _past_apples(cycle, make, plan, detours, allowed, neighbours):
    """``(plan, detours)``: each joint move of the clear ``plan`` (made by ``make(detours)``) that passes one of
    the ``neighbours`` faster than their speed, or presses one off its stem, made the quickest of: taken around the
    apples (:func:`_around_apples`), or slowed only over its stretch past them (:func:`_window`) or slowed whole,
    until it passes none fast (at most to MIN_SLOW of its speed; :func:`_slowed`); a move that presses an apple is
    slowed on a way around the apples it presses (touching others slowly) where one is found. A move that none of
    these helps keeps its path (the apple it passes may bruise or come off)."""
    checker = cycle.checker
    tried, slow = set(), {}
    while True:
        touch, seg = _fast_touch(checker, plan, neighbours, [label for label in DETOURS if label not in tried])
        if touch is None:
            if slow:
                plan.extra['slowed'] = ', '.join(f'{label} to {s}' for label, s in slow.items())
            return plan, detours
        tried.add(seg.label)
        around = _around_apples(cycle, make, plan, seg, detours, slow, allowed, neighbours)
        ways = [] if around is None else [(around[0], slow, around[1])]
        base = (plan, detours)
        # No speed keeps an apple pressed from above on its stem: the slowed ways start from a way around it.
        if _fast_touch(checker, plan, neighbours, [seg.label], fast=False)[0] is not None:
            base = _around_apples(cycle, make, plan, seg, detours, slow, allowed, neighbours, fast=False) or base
        start, start_detours = base
        fast = _fast_touch(checker, start, neighbours, [seg.label], pressing=False)[0]
        if fast is None:
            ways.append((start, slow, start_detours))
        else:
            move = next(x for x in start.segments if x.label == seg.label)
            window = _window(cycle, start, move, neighbours)
            for within in ([None] if window is None else [window, None]):
                ways.append(_slowed(cycle, make, seg.label, fast, start_detours, slow, within, allowed, neighbours))
        ways = [w for w in ways if w is not None]
        gentle = [w for w in ways if _fast_touch(checker, w[0], neighbours, [seg.label], fast=False)[0] is None]
        if ways:
            plan, slow, detours = min(gentle or ways, key=lambda w: w[0].duration)


def _slowed(cycle, make, label, touch, detours, slow, window, allowed, neighbours):
    """``(plan, slow, detours)`` with joint move ``label`` (whose fastest pass of an apple is ``touch``) slowed
    past ``window`` (:class:`Slowed`) just enough that it passes no apple fast; a slowed move that hits an
    obstacle taken around it again (:func:`_detoured`); None when no fraction down to MIN_SLOW makes a clear
    plan."""
    fraction = 1.0
    while fraction > MIN_SLOW:
        fraction = max(MIN_SLOW, fraction * SLOW_MARGIN * touch.limit / touch.speed)
        slower = {**slow, label: Slowed(fraction, window)}
        try:
            again, again_detours, contact = _detoured(cycle, make, allowed, detours, slower)
        except (Unreachable, ValueError):         # (no timing within the limits through the slowed legs)
            return None
        if contact is not None:
            return None
        still = _fast_touch(cycle.checker, again, neighbours, [label], pressing=False)[0]
        if still is None:
            return again, slower, again_detours
        touch = still
    return None


def _window(cycle, plan, seg, neighbours):
    """``(first, last)``: the configurations of joint move ``seg`` of ``plan`` WINDOW_PAD s before and after its
    stretch within reach of the apples (None at the move's own ends); None when that stretch is the whole move."""
    t, q = cycle.checker.samples(plan.trajectory)
    inside = np.flatnonzero((t >= seg.start) & (t <= seg.start + seg.duration))
    near = np.flatnonzero(neighbours.touching(q[inside, :cycle.arm.dof + 1]))
    if not len(near):
        return None
    t_in, t_out = t[inside[near[0]]] - WINDOW_PAD, t[inside[near[-1]]] + WINDOW_PAD
    if t_in <= seg.start and t_out >= seg.start + seg.duration:
        return None
    ends = plan.trajectory.sample([t_in, t_out])[0][:, :cycle.arm.dof]
    return (None if t_in <= seg.start else ends[0]), (None if t_out >= seg.start + seg.duration else ends[1])


def _around_apples(cycle, make, plan, seg, detours, slow, allowed, neighbours, fast=True):
    """``(plan, detours)`` with the joint move ``seg`` of ``plan`` taken around the ``neighbours``: through the
    waypoints of a joint path clear of them (``fast`` False: pressing none off its stem, touching them allowed) and
    of the obstacles (the apples its own ends touch, slowly there, are passed as they are), twice as many of them
    while the timed move still cuts past an apple fast (or presses one), up to REFINE times; None when no such path
    is found, or the plan made that way is not clear."""
    checker, arm = cycle.checker, cycle.arm
    ends = np.asarray(plan.trajectory.sample([seg.start, seg.start + seg.duration])[0])[:, :arm.dof + 1]
    # The fingers as wide as at either end of the move, all along the search (the arm's own joints come first).
    fingers = ends[:, arm.dof:].max(axis=0)
    ignore = neighbours.touched_at(np.column_stack([ends[:, :arm.dof], np.tile(fingers, (2, 1))]))
    ends = ends[:, :arm.dof]

    def in_the_way(x):
        x = np.atleast_2d(x)
        held = np.column_stack([x, np.tile(fingers, (len(x), 1))])
        return checker.colliding(x, allowed) | (neighbours.touching(held, ignore) if fast else
                                                 neighbours.pressing(held, ignore))
    try:
        path = rrt_connect(in_the_way, ends[0], ends[1], arm.lower, arm.upper, iterations=PAST_APPLES_TRIES)
    except NoPath:
        return None
    if len(path) <= 2:
        # The straight way in joint space passes no apple, but the timed move (each joint on its own time)
        # bends away from it: held to it by points along it.
        path = ends[0] + np.linspace(0.0, 1.0, STRAIGHT + 2)[:, None] * (ends[1] - ends[0])
    for _ in range(REFINE + 1):
        around = {**detours, seg.label: list(path[1:-1])}
        try:
            again = make(around, slow)
        except Unreachable:
            return None
        if check(checker, again, allowed) is not None:
            return None
        if _fast_touch(checker, again, neighbours, [seg.label], fast=fast)[0] is None:
            return again, around
        path = doubled(path)
    return None


def _fast_touch(checker, plan, neighbours, labels, pressing=True, fast=True):
    """``(touch, segment)``: the first :class:`~picking_core.collision.fruit.FastTouch` of ``plan`` (at the checker's
    samples) within its segments labelled one of ``labels`` (``fast``: an apple passed too fast; ``pressing``: one
    pressed off its stem, but for those a move's own ends touch: it cannot help them), and that segment;
    ``(None, None)`` without one."""
    segments = sorted((s for s in plan.segments if s.label in labels), key=lambda s: s.start)
    if not segments:
        return None, None
    t, q = checker.samples(plan.trajectory)
    q = q[:, :checker.capsules.arm.dof + 1]
    for s in segments:
        inside = (t >= s.start) & (t <= s.start + s.duration)
        if inside.sum() < 2:
            continue
        spare = neighbours.touched_at(q[inside][[0, -1]]) if pressing else ()
        touch = neighbours.first_fast_touch(t[inside], q[inside], pressing=pressing, spare=spare, fast=fast)
        if touch is not None:
            return touch, s
    return None, None


def check(checker, plan, allowed):
    """The first contact of ``plan`` (its arm joints), with the part of the cycle it happens in."""
    contact = checker.check(plan.trajectory, allowed)
    if contact is None:
        return None
    where = next((seg.label for seg in plan.segments if seg.start <= contact.time <= seg.start + seg.duration), '')
    return PartContact(contact, where)


class PartContact:
    """A contact and the part of the cycle it happens in."""

    def __init__(self, contact, part):
        self.contact, self.part = contact, part
        self.obstacle = contact.obstacle

    def __str__(self):
        return f'{self.contact} ({self.part})' if self.part else str(self.contact)


def screen(cycle, approaches, allowed, enough=None):
    """``(passed, blocked)``: the approaches whose approach and lift lines are reachable every
    SCREEN_STEP without a jump and clear, quickest first by an estimate (the slowest joint's travel
    from home to P1 and from P3 back, at full speed); and the joints along the lines of those that
    only a collision stopped (for :func:`_named`), one (n, dof) array each. All candidates' IK at
    once; their collision checks a batch at a time, quickest first, until ``enough`` have passed
    (None: all): only the first few passed are planned, so the rest need no check."""
    arm, checker = cycle.arm, cycle.checker
    if not approaches:
        return [], []
    home = np.asarray(cycle.s.home_positions, float)
    keys = [cycle.key_poses(a.pose, a.lift) for a in approaches]
    P1, P2, P3 = (np.array([k[name] for k in keys]) for name in ('P1', 'P2', 'P3'))
    q1, ok1, _ = arm.ik_batch(P1, home)
    for c, a in enumerate(approaches):
        if a.branch is not None:
            q1[c], ok1[c] = a.branch, True
    # Every candidate's lines are as long as the settings make them: the same number of points. The cycle's
    # lines keep the grasp's orientation (P1 and P3 are P2 moved back along the grasp axis and up).
    n1, n3 = (max(2, int(np.ceil(d / SCREEN_STEP - 1e-9)) + 1) for d in (cycle.s.approach_distance, cycle.s.lift_height))
    f = np.concatenate([np.linspace(0.0, 1.0, n1), 1.0 + np.linspace(0.0, 1.0, n3)[1:]])
    n = len(f)
    a, b = np.where(f <= 1.0, 0, 1), np.clip(f - np.where(f <= 1.0, 0.0, 1.0), 0.0, 1.0)
    starts = np.stack([P1[:, :3, 3], P2[:, :3, 3]], axis=1)[:, a]             # (C, n, 3)
    ends = np.stack([P2[:, :3, 3], P3[:, :3, 3]], axis=1)[:, a]
    P = np.repeat(P2[:, None], n, axis=1)
    P[:, :, :3, 3] = starts + b[None, :, None] * (ends - starts)
    q, ok, _ = arm.ik_batch(P.reshape(-1, 4, 4), np.repeat(np.where(ok1[:, None], q1, home), n, axis=0))
    q, ok = q.reshape(len(keys), n, -1), ok.reshape(len(keys), n) & ok1[:, None]
    good = ok.all(axis=1)
    with np.errstate(invalid='ignore'):
        good &= np.nan_to_num(np.abs(np.diff(q, axis=1)), nan=np.inf).max(axis=(1, 2)) <= SCREEN_JUMP
    vmax = np.where(np.isfinite(arm.max_velocity), arm.max_velocity, 1.0)
    with np.errstate(invalid='ignore'):
        cost = np.max(np.abs(q[:, 0] - home) / vmax, axis=1) + np.max(np.abs(home - q[:, -1]) / vmax, axis=1)
    order = [c for c in np.argsort(cost, kind='stable') if good[c]]
    if checker is None:
        return [approaches[c] for c in order], []
    passed, blocked = [], []
    # A few points of each line first (a candidate blocked is mostly blocked at several), the rest only for
    # the candidates those leave: the same points checked in all, most blocked candidates at a third of them.
    coarse = np.zeros(n, bool)
    coarse[::SCREEN_COARSE] = True
    for first in range(0, len(order), SCREEN_BATCH):
        rows = np.array(order[first:first + SCREEN_BATCH])
        hit = np.zeros(len(rows), bool)
        for points in (coarse, ~coarse):
            left = np.nonzero(~hit)[0]
            if not len(left) or not points.any():
                continue
            sub = q[rows[left]][:, points]
            hit[left] = checker.colliding(sub.reshape(-1, q.shape[-1]), allowed).reshape(len(left), -1).any(axis=1)
        passed += [approaches[c] for c in rows[~hit]]
        blocked += [q[c] for c in rows[hit]]
        if enough is not None and len(passed) >= enough:
            break
    return passed, blocked


def _named(checker, blocked, allowed):
    """``(blockers, first)``: a Counter of the obstacles that stopped the first NAMED of the ``blocked``
    lines (joints along each, from :func:`screen`), and the first line's contact (None without any):
    the words of a refusal, looked up only when one is made."""
    blockers, first = Counter(), None
    for q in blocked[:NAMED]:
        contact = checker.first_contact(q, allowed=allowed)
        if contact is not None:
            blockers[contact.obstacle] += 1
            first = contact if first is None else first
    return blockers, first
