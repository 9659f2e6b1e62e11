"""A tree's apples picked one after another (pure core, no ROS).

:class:`Harvest` checks every apple's reach (step C), orders the reachable ones for the least
planned time, and chains their pick cycles (:class:`~picking_core.pick_cycle.PickCycle`): after
each release the arm rises out of the box straight into the next apple's approach, and goes home
only after the last. The order is chosen on the joint-space moves between the apples (the box,
then the next apple's approach pose, estimated with :meth:`Planner.move_times
<picking_core.planning.limits.Limits.move_times>`): the waist's swing dominates them, which
a Euclidean distance between apples does not see.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from scipy.spatial.transform import Rotation

from . import trajectory
from .collision.fruit import Neighbours
from .kinematics import Unreachable
from .moving_pick import aim, closing_margin, sure
from .planning import Plan


@dataclass(frozen=True)
class AppleTimes:
    """One apple of a harvest plan: its index in the goal and when its cycle runs, s from the plan's
    start (``end``: its release ends, the apple is in the box); ``held``: from when to when the closed
    fingers carry it (its grasp's end to its release's start), or None (a plan without a gripper)."""

    index: int
    start: float
    end: float
    held: tuple | None = None


@dataclass(frozen=True)
class Skipped:
    """An apple left on the tree: its index in the goal and why."""

    index: int
    reason: str


@dataclass(frozen=True)
class HarvestPlan:
    """A harvest, planned.

    Attributes
    ----------
    plan : Plan
        Every cycle, one after another, then home; segments labelled ``apple <index>: <part>``.
    apples : tuple of AppleTimes
        In the order they are picked.
    skipped : tuple of Skipped
    ordered, given : float
        s, the estimated time of the moves between the apples (home to the first, box to the next,
        the last box to home) in the planned order and in the goal's order.
    ordering_s : float
        s the ordering took.
    empty_below : float
        m: a measured finger opening below this while an apple should be in them holds nothing (0: not
        judged).
    """

    plan: Plan
    apples: tuple = ()
    skipped: tuple = ()
    ordered: float = 0.0
    given: float = 0.0
    ordering_s: float = 0.0
    empty_below: float = 0.0

    def picked_by(self, t):
        """The apples in the box at ``t`` s from the plan's start."""
        return [a for a in self.apples if a.end <= t + 1e-9]


def route_cost(route, first, between, last):
    """The estimated time of visiting the apples in ``route``: ``first[j]`` to the first,
    ``between[i, j]`` from one to the next, ``last[i]`` after the last."""
    route = np.asarray(route, int)
    if route.size == 0:
        return 0.0
    return float(first[route[0]] + between[route[:-1], route[1:]].sum() + last[route[-1]])


#: Up to this many apples the order is exact (Held-Karp); beyond, a local search.
EXACT = 10
#: First apples tried by the local search (the nearest ones from the start).
STARTS = 3


def best_order(first, between, last, passes=20):
    """The visiting order (indices into the cost arrays) of least :func:`route_cost`: exact up to
    EXACT apples; beyond, nearest neighbour from each of the STARTS nearest first apples, each improved
    by reversing stretches (2-opt) and moving single apples (or-opt) until neither helps. Never worse
    than the given order (0, 1, ...)."""
    first, between, last = (np.asarray(x, float) for x in (first, between, last))
    n = len(first)
    if n < 2:
        return list(range(n))
    if n <= EXACT:
        route = _exact(first, between, last)
    else:
        routes = [_improved(_nearest(k, between, n), first, between, last, passes)
                  for k in np.argsort(first)[:STARTS]]
        route = min(routes, key=lambda r: route_cost(r, first, between, last))
    given = list(range(n))
    return route if route_cost(route, first, between, last) <= route_cost(given, first, between, last) else given


def _exact(first, between, last):
    """The best route by dynamic programming over the subsets of apples visited (Held-Karp)."""
    n = len(first)
    cost = np.full((1 << n, n), np.inf)
    came = np.zeros((1 << n, n), int)
    for j in range(n):
        cost[1 << j, j] = first[j]
    for mask in range(1, 1 << n):
        inside = [j for j in range(n) if mask >> j & 1]
        if len(inside) < 2:
            continue
        for j in inside:
            rest = mask ^ (1 << j)
            via = cost[rest] + between[:, j]
            i = int(np.argmin(via))
            cost[mask, j], came[mask, j] = via[i], i
    mask, j = (1 << n) - 1, int(np.argmin(cost[-1] + last))
    route = []
    while mask:
        route.append(j)
        mask, j = mask ^ (1 << j), came[mask, j]
    return route[::-1]


def _nearest(k, between, n):
    """Nearest neighbour from apple ``k``."""
    route, left = [int(k)], set(range(n)) - {int(k)}
    while left:
        j = min(left, key=lambda m: between[route[-1], m])
        route.append(j)
        left.remove(j)
    return route


def _improved(route, first, between, last, passes):
    """``route`` improved by 2-opt and or-opt moves until none helps (or ``passes`` rounds)."""
    n = len(route)
    cost = route_cost(route, first, between, last)
    for _ in range(passes):
        improved = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                for candidate in (route[:i] + route[i:j + 1][::-1] + route[j + 1:],      # 2-opt
                                  route[:i] + route[i + 1:j + 1] + [route[i]] + route[j + 1:],  # or-opt, later
                                  route[:i] + [route[j]] + route[i:j] + route[j + 1:]):  # or-opt, earlier
                    c = route_cost(candidate, first, between, last)
                    if c < cost - 1e-9:
                        route, cost, improved = candidate, c, True
        if not improved:
            break
    return route


#: m: an arm at rest with its tool this near the box's drop point is in the box (a harvest starts there).
IN_BOX = 0.01
#: Roll, pitch, yaw of a synthetic tree's grasps, rad: the tool's z axis along +x, into the canopy.
SIDEWAYS = (0.0, np.pi / 2, 0.0)


def synthetic_tree(n, seed=0, low=(0.55, -0.35, 0.40), high=(0.80, 0.35, 0.85), spacing=0.08, rpy=SIDEWAYS):
    """``n`` apples of a seeded random tree: 4x4 grasp poses in the base frame, each at least
    ``spacing`` m from the others within the box ``low``..``high`` (m), grasped along ``rpy``.
    Raises ValueError when that many do not fit."""
    rng = np.random.default_rng(seed)
    R = Rotation.from_euler('xyz', rpy).as_matrix()
    points = np.empty((0, 3))
    while len(points) < n:               # candidates in batches; each kept if clear of those kept before
        before = len(points)
        for p in rng.uniform(low, high, (8 * n, 3)):
            if len(points) == n:
                break
            if not len(points) or np.min(np.sum((points - p) ** 2, axis=1)) >= spacing ** 2:
                points = np.vstack([points, p])
        if len(points) == before:        # a whole batch found no room: the box is full
            break
    if len(points) < n:
        raise ValueError(f'{n} apples {spacing} m apart do not fit between {low} and {high} m')
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, :3, :3] = R
    poses[:, :3, 3] = points
    return list(poses)


class Unsure(ValueError):
    """A swaying apple's closing would not be sure (:func:`~picking_core.moving_pick.sure`)."""


class Harvest:
    """Plans a harvest with a :class:`~picking_core.pick_cycle.PickCycle`."""

    def __init__(self, cycle):
        self.cycle = cycle
        self.arm = cycle.arm
        self.home = np.asarray(cycle.s.home_positions, float)
        self._cycles = {}   # cycles planned, by their start, apple and gripper: a coordinator plans many harvests

    def _cycle(self, state, T, gripper, chained, on_tree=(), sway=None):
        """The cycle of apple ``T`` from ``state``, passing the apples ``on_tree`` (centres, m; ``sway`` (n, 2) how
        each strays, :class:`~picking_core.collision.fruit.Neighbours`) no faster than the settings'
        ``apple_pass_speed`` (with a checker); remembered: the same inputs plan the same cycle."""
        checker, speed = self.cycle.checker, self.cycle.s.apple_pass_speed
        on_tree = np.asarray(on_tree, float).reshape(-1, 3)
        sway = np.zeros((len(on_tree), 2)) if sway is None else np.asarray(sway, float).reshape(-1, 2)
        if checker is None or speed <= 0.0:
            on_tree, sway = on_tree[:0], sway[:0]   # not looked at: the same cycle whatever hangs beside it
        key = (tuple(np.asarray(x, float).tobytes() for x in state), np.asarray(T, float).tobytes(), gripper, chained,
               on_tree.tobytes(), sway.tobytes())
        if key not in self._cycles:
            neighbours = Neighbours(checker.capsules, on_tree, speed, sway=sway) if len(on_tree) else None
            try:
                self._cycles[key] = self.cycle.plan(state, T, gripper, from_box=chained, home_after=False,
                                                    neighbours=neighbours)
            except (Unreachable, ValueError) as exc:
                self._cycles[key] = exc
            if len(self._cycles) > 4096:
                self._cycles.pop(next(iter(self._cycles)))
        found = self._cycles[key]
        if isinstance(found, Exception):
            raise found
        return found

    def _aimed(self, state, T, gripper, chained, on_tree, follow, t, sway=None):
        """The cycle of a swaying apple (``follow``, a :class:`~picking_core.moving_pick.Follow`; ``t`` the clock time
        the cycle starts at) from ``state``: aimed where the apple will be when the fingers close and riding it
        over the straight approach, as a pick of it is (:func:`~picking_core.moving_pick.aim`). ValueError when the
        closing would not be sure (:func:`~picking_core.moving_pick.sure`): the apple is left on the tree, never
        closed on air."""
        checker, speed = self.cycle.checker, self.cycle.s.apple_pass_speed
        on_tree = np.asarray(on_tree, float).reshape(-1, 3)
        neighbours = Neighbours(checker.capsules, on_tree, speed, sway=sway) if checker is not None and \
            speed > 0.0 and len(on_tree) else None

        def plan_to(T_aim, least):
            return self.cycle.plan(state, T_aim, gripper, from_box=chained, home_after=False, neighbours=neighbours,
                                   approach_time=least, rides=True)
        # All of the motion or none: aimed once, from the box, the prediction looks a whole approach ahead and is
        # never refreshed; a share of a ride on it pushed apples off rather than kept them still (docs/decisions.md).
        aimed = aim(plan_to, lambda s: follow.predict(t + s), np.asarray(T, float)[:3, :3], follow.width,
                    ride=partial(self.cycle.ride, shares=(1.0,)))
        if not sure(aimed):
            raise Unsure(f'its sway is too unsure to close on (the fingers would miss it by '
                             f'{-closing_margin(aimed) * 1e3:.0f} mm at one deviation): left on the tree')
        return replace(aimed.plan, extra={**aimed.plan.extra, 'closes_in': aimed.at})

    def in_box(self, start):
        """True when ``start = (q, qd, qdd)`` rests with the tool at the box's drop point (a harvest
        replacing another starts there, after the apple in hand is dropped)."""
        q, qd, qdd = (np.asarray(x, float)[:self.arm.dof] for x in start)
        return bool(np.abs(qd).max() < 1e-9 and np.abs(qdd).max() < 1e-9
                    and np.linalg.norm(self.arm.fk(q)[:3, 3] - np.asarray(self.cycle.s.box_position)) < IN_BOX)

    def reach(self, apples, indices=None):
        """``(ok, skipped)``: for each reachable apple ``(index, T, q at P1, q above the box after it)``;
        for the others a :class:`Skipped` with the knot point that cannot be reached. ``indices``: each
        apple's index in its goal (default: its place in ``apples``)."""
        ok, skipped = [], []
        for i, T in zip(range(len(apples)) if indices is None else indices, apples):
            try:
                poses = self.cycle.key_poses(T)
                q = {}
                seed = self.home
                for name in ('P1', 'P2', 'P3'):
                    q[name] = seed = self.arm.check_reachable(poses[name], seed=seed)
                if self.cycle.s.place_yaw_free:
                    _, q_top, _ = self.cycle.quickest_place(poses, q['P3'], self.home)
                else:
                    q_top = self.arm.check_reachable(poses['P4'], seed=q['P3'])
                ok.append((i, np.asarray(T, float), q['P1'], q_top))
            except Unreachable as exc:
                skipped.append(Skipped(i, f'unreachable: {exc}'))
        return ok, skipped

    def order(self, ok, q_from):
        """The visiting order of the reachable apples ``ok`` (as :meth:`reach` gives them), starting at
        ``q_from`` and ending home: ``(ok reordered, estimated s in that order, in the given order)``."""
        if not ok:
            return [], 0.0, 0.0
        first, between, last = self.order_costs(ok, q_from)
        route = best_order(first, between, last)
        return ([ok[k] for k in route], route_cost(route, first, between, last),
                route_cost(range(len(ok)), first, between, last))

    def order_costs(self, ok, q_from):
        """``(first, between, last)``, the estimated moves an order is judged on (s): from ``q_from`` to each
        apple's approach, from above the box after apple i to apple j's, and from above the box home."""
        q1 = np.array([a[2] for a in ok])
        q_top = np.array([a[3] for a in ok])
        times = self.cycle.planner.move_times
        first = times(np.asarray(q_from, float)[None], q1)[0]
        between = times(q_top, q1)
        np.fill_diagonal(between, 0.0)
        last = times(q_top, self.home[None])[:, 0]
        return first, between, last

    def plan(self, start, apples, gripper_start=None, ordered=True, indices=None, follows=None, t0=0.0):
        """The harvest of ``apples`` (4x4 grasp poses in the base frame) from ``start = (q, qd, qdd)``;
        ``indices``: each apple's index in its goal (default: its place in ``apples``). ``follows`` maps the index
        of a swaying apple to its :class:`~picking_core.moving_pick.Follow` (its ``T`` where it hangs, its
        prediction on a clock on which the plan starts at ``t0`` s): the plan's first cycle, if its apple sways, is
        aimed where the apple will be at the closing and rides it (:meth:`_aimed`); a later one is planned where its
        apple hangs (an aim would look a cycle or more ahead: the rest is aimed again before each apple in hand is
        dropped). A first apple whose closing would not be sure is put off to the end of the order (judged again if
        its turn comes first), and left on the tree when no other apple is left. The order is chosen on where the
        apples hang.

        From rest in the box (:meth:`in_box`: a harvest replacing one whose apple in hand has just been
        dropped) the arm rises out of it to the first apple; from anywhere else it goes by way of home.
        ``ordered=False`` keeps the goal's order. Apples out of reach, or whose cycle cannot be
        planned, are skipped with the reason. Raises ValueError when none is left.
        """
        began = time.perf_counter()
        from_box = self.in_box(start)
        ok, skipped = self.reach(apples, indices)
        q_from = self.home if not from_box else np.asarray(start[0], float)[:self.arm.dof]
        if ordered:
            ok, est, given = self.order(ok, q_from)
        else:
            _, _, given = self.order(ok, q_from)
            est = given
        ordering_s = time.perf_counter() - began
        plans, times, state, gripper, chained = [], [], start, gripper_start, from_box
        t = 0.0
        # Every apple of the goal hangs on the tree until its own cycle picks it (those skipped stay).
        on_tree = dict(zip(range(len(apples)) if indices is None else indices,
                           (np.asarray(T, float)[:3, 3] for T in apples)))
        # How far and how fast each swaying apple strays: the moves keep off it and pass it slower by that much.
        sway = {i: f.reach(on_tree[i], t0) for i, f in (follows or {}).items() if i in on_tree}
        queue, put_off = list(ok), set()
        while queue:
            index, T, q1, q_top = queue.pop(0)
            others = [i for i in on_tree if i != index]
            centres, swaying = [on_tree[i] for i in others], [sway.get(i, (0.0, 0.0)) for i in others]
            follow = (follows or {}).get(index) if not plans else None
            try:
                p = self._cycle(state, T, gripper, chained, centres, swaying) if follow is None else \
                    self._aimed(state, T, gripper, chained, centres, follow, t0 + t, swaying)
            except Unsure as exc:
                if queue and index not in put_off:
                    # (Its sway may be surer in a later turn: seen longer, no longer behind the arm.)
                    put_off.add(index)
                    queue.append((index, T, q1, q_top))
                else:
                    skipped.append(Skipped(index, str(exc)))
                continue
            except (Unreachable, ValueError) as exc:
                skipped.append(Skipped(index, str(exc)))
                continue
            on_tree.pop(index)
            plans.append((f'apple {index}', p))
            held = (t + p.extra['grasp_end'], t + p.extra['release_start']) \
                if 'grasp_end' in p.extra and 'release_start' in p.extra else None
            times.append(AppleTimes(index, t, t + p.duration, held))
            t += p.duration
            q_end = p.trajectory.end_state()[0]
            state = (q_end[:self.arm.dof], np.zeros(self.arm.dof), np.zeros(self.arm.dof))
            gripper, chained = float(q_end[-1]), True
        if not plans:
            reasons = '; '.join(f'apple {s.index}: {s.reason}' for s in sorted(skipped, key=lambda s: s.index))
            raise ValueError(f'no apple can be picked ({reasons})' if skipped else 'the harvest has no apples')
        plans.append(('home', self.cycle.back_home(state, gripper)))
        skipped = tuple(sorted(skipped, key=lambda s: s.index))
        plan = replace(_joined(plans), extra=dict(apples=len(times), skipped=len(skipped), order_estimate=est,
                                                  given_order_estimate=given, ordering_ms=ordering_s * 1e3))
        return HarvestPlan(plan, tuple(times), skipped, est, given, ordering_s, empty_below(self.cycle.s.gripper_closed))


#: m: an apple seen this near one a harvest has (picked, in hand or to come) is that apple.
KNOWN_APPLE = 0.05
#: s an apple must have been seen hanging still before a running harvest takes it in (FruitMap.targets: an apple
#: the arm carries past, holds over the box or knocked swinging is not).
SETTLED = 1.0
#: m: an apple seen this near the box's drop point is one the arm has let go of, never one to pick.
BOX_CLEAR = 0.15


def new_apples(seen, known, box, near=KNOWN_APPLE, clear=BOX_CLEAR):
    """The grasp poses of ``seen`` (4x4 each) that are no apple a harvest knows: farther than ``near`` m from every
    place of ``known`` ((N, 3) m, its apples, picked or not) and from each other's, and farther than ``clear`` m from
    ``box`` (3,), the drop point. The camera shows an apple the arm hid at home, or one behind an apple just
    picked, only as the harvest runs: these join its apples still to come."""
    places = [np.asarray(p, float) for p in np.asarray(known, float).reshape(-1, 3)]
    out = []
    for T in seen:
        p = np.asarray(T, float)[:3, 3]
        if np.linalg.norm(p - np.asarray(box, float)) <= clear:
            continue
        if places and min(np.linalg.norm(p - q) for q in places) <= near:
            continue
        out.append(np.asarray(T, float))
        places.append(p)
    return out


class HarvestGoal:
    """``plan(start, gripper)`` of a harvest goal, as the planner node calls every goal's: the
    harvest of ``apples`` (their ``indices`` in the goal: by default their places) from ``start``;
    the :class:`HarvestPlan` it made is kept in ``last``."""

    def __init__(self, harvest, apples, indices=None, why='', after=np.inf):
        self.harvest, self.apples, self.last = harvest, list(apples), None
        self.indices = list(range(len(self.apples))) if indices is None else list(indices)
        # The rest of a running harvest planned again (see rest): why, and the latest start (the end of the
        # apple in hand; any later, the running plan has started one of these apples).
        self.why, self.after = why, after
        self.continues = bool(why)

    def __call__(self, start, gripper=None):
        self.last = self.harvest.plan(start, self.apples, gripper_start=gripper, indices=self.indices)
        return self.last.plan

    def rest(self, harvest, indices, why, after):
        """The same goal's apples ``indices`` (not started by ``after``, s), to be planned with ``harvest``
        (a new world's) to start no later: a harvest planned again around what changed (``why``, in words)."""
        pose = dict(zip(self.indices, self.apples))
        return HarvestGoal(harvest, [pose[i] for i in indices], indices, why, after)


#: s after an apple's planned release that it is reported in the box (a loaded controller runs a
#: little behind the plan's clock).
REPORT_MARGIN = 0.1
#: m above the closed fingers' opening that they must stay while they carry an apple: half the gap between
#: the closed fingers (5.5 cm) and the smallest apple (6 cm); closed on air they come down to the closed opening.
HOLDING_MARGIN = 0.0025
#: s after the grasp's end that the fingers are judged (a drive reaches its stop a little after its command).
GRIP_SETTLE = 0.1


def empty_below(gripper_closed):
    """m: an opening measured below this while the fingers carry an apple means they hold nothing."""
    return gripper_closed + HOLDING_MARGIN


def carried(opening, empty):
    """Whether fingers whose newest opening while they carried an apple was ``opening`` (m; None: not measured)
    held it, ``empty`` being :func:`empty_below`: True, False or None. The newest reading decides, not the
    narrowest: fingers that lose the apple close and stay closed, while a dip as they settle on it (a squeeze, a
    contact the gripper's sensing reports late) passes."""
    return None if opening is None else bool(opening >= empty)


def carrying(held, t):
    """Whether ``t`` s into a plan the fingers carry an apple they took, settled on it: ``held`` is the carry's
    (grasp end, release start), s into the plan (None: a plan without a gripper)."""
    return held is not None and held[0] + GRIP_SETTLE <= t <= held[1]


class HarvestRun:
    """A harvest plan sent to start at ``start`` (s, the controller's clock): which apples are in the
    box by a time, and the harvest's summary when it ends. ``until``: when a harvest that replaced it
    took over (its apples picked by then are its own). ``before``: the run of the same goal that this
    one carries on from (planned again around a changed world): its apples in the box by then count."""

    def __init__(self, plan, start, before=None):
        self.plan, self.start, self.until, self.before = plan, start, np.inf, before
        self.reported = 0 if before is None else before.reported
        self.first = start if before is None else before.first      # when the goal's harvest began
        # The goal's apples (by index): the narrowest opening measured while each was carried; and those missed.
        self.grip = {} if before is None else before.grip
        self.missed = {} if before is None else before.missed

    def watch(self, t, opening):
        """The fingers measured at ``opening`` (m) at ``t`` (the controller's clock): the newest opening of the
        apple they carry then (see :func:`carried`), this run's or, until this one takes over, the run's before
        it (the apple in hand when the rest was planned)."""
        if self.before is not None and t < self.before.until:
            self.before.watch(t, opening)
        if self.plan.empty_below <= 0.0 or t >= self.until:
            return
        for a in self.plan.apples:
            if carrying(a.held, t - self.start):
                self.grip[a.index] = float(opening)

    def holding(self, apple):
        """Whether the fingers held ``apple`` (an AppleTimes) at the end of its carry: True, False (they closed
        on nothing, or lost it), None (not measured: no gripper, or no joint_states then)."""
        return carried(self.grip.get(apple.index), self.plan.empty_below)

    def miss(self, apple, why):
        """``apple`` was not in the fingers (``why``, in words): not counted as picked."""
        self.missed[apple.index] = why

    def _earlier(self):
        """The apples the runs before this one put in the box, and the apples they skipped."""
        if self.before is None:
            return [], []
        picked, skipped = self.before._earlier()
        return picked + self.before.plan.picked_by(self.start - self.before.start), skipped + list(self.before.plan.skipped)

    def in_the_box_after(self, t):
        """``(at, plan_time)``: the earliest time from ``t`` at which the arm rests in the box with no apple in
        hand, and that time in this run's plan (s from its start): the start of this run if it took over from
        another there and has not begun by ``t``, else the end of the apple whose cycle runs at ``t``; None once
        the last apple is in the box."""
        if self.before is not None and t <= self.start:
            return self.start, 0.0
        return next(((self.start + a.end, a.end) for a in self.plan.apples if self.start + a.end >= t), None)

    def after_apple_in_hand(self, t):
        """The time of :meth:`in_the_box_after` (``t`` itself once the last apple is in the box)."""
        found = self.in_the_box_after(t)
        return t if found is None else found[0]

    def picked_by(self, t):
        """The apples in the box by ``t`` (by the plan's clock, less REPORT_MARGIN), in picking order."""
        if self.before is not None and t < self.start:
            return self.before.picked_by(t)
        earlier = self._earlier()[0]
        if t >= self.until:                  # replaced: the harvest that took over started after its apple in hand
            return earlier + list(self.plan.picked_by(self.until - self.start))
        return earlier + list(self.plan.picked_by(t - self.start - REPORT_MARGIN))

    def in_hand(self, t):
        """The apple whose cycle runs at ``t`` (and was not finished), or None (also once replaced)."""
        if t >= self.until:
            return None
        if self.before is not None and t < self.start:
            return self.before.in_hand(t)
        rel = t - self.start
        return next((a for a in self.plan.apples if a.start <= rel < a.end + REPORT_MARGIN
                     and a not in self.picked_by(t)), None)

    def newly_picked(self, t):
        """``(k, apple)`` of the apples in the box by ``t`` not reported before (``k`` counts from 1)."""
        picked = self.picked_by(t)
        new = list(enumerate(picked[self.reported:], start=self.reported + 1))
        self.reported = len(picked)
        return new

    def summary(self, t, finished):
        """Figures of the harvest ending at ``t``: all its apples if it ``finished``, else those in the box by then
        (with those of the runs it carries on from)."""
        earlier, skipped = self._earlier()
        skipped = sorted(skipped + list(self.plan.skipped), key=lambda x: x.index)
        done = earlier + list(self.plan.apples) if finished else self.picked_by(t)
        picked = [a for a in done if a.index not in self.missed]
        end = self.start + self.plan.plan.duration if finished else max(min(t, self.until), self.first)
        took = end - self.first
        return dict(picked=len(picked), missed=len(done) - len(picked), skipped=len(skipped),
                    planned=len(earlier) + len(self.plan.apples),
                    harvest_time=took, apples_per_hour=3600.0 * len(picked) / took if took > 0 else 0.0,
                    picked_apples=' '.join(str(a.index) for a in picked),
                    missed_apples=' '.join(str(a.index) for a in done if a.index in self.missed),
                    skipped_apples=' '.join(str(x.index) for x in skipped))

    def words(self, t, finished):
        """The summary in words."""
        s = self.summary(t, finished)
        missed = f"{s['missed']} missed (the fingers held nothing), " if s['missed'] else ''
        return (f"{s['picked']} of {s['planned']} apples picked, {missed}{s['skipped']} skipped, "
                f"{s['harvest_time']:.1f} s, {s['apples_per_hour']:.0f} apples/h")


def _joined(plans):
    """One Plan of the ``(prefix, Plan)`` pairs, one after another; segment labels prefixed."""
    segments, cartesian, t, offset = [], [], 0.0, 0
    for prefix, p in plans:
        segments += [replace(s, label=f'{prefix}: {s.label}', start=s.start + t) for s in p.segments]
        cartesian += [(k + offset, path) for k, path in p.cartesian]
        t += p.duration
        offset += len(p.segments)
    first = plans[0][1]
    return Plan(trajectory.concatenate([p.trajectory for _, p in plans]), 'harvest', segments, cartesian,
                first.joint_names)
