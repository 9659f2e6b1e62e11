"""A harvest of the apples a camera sees, played through the fruit world (pure): how the planner's harvest from the
camera does by the world's own count, for the tests and the benchmarks.

The camera watches the tree from home for ``look`` s; the harvest of the apples the fruit map then confirms is
planned and played through the world (:class:`~picking_core.fruit.FruitWorld`), the camera capturing at its rate
with the arm where it is at each capture and the branches hiding what they hide, each frame handed to the fruit map
after its latency, as picking-sim's and picking-planner's are. As in the planner (``GoalRunner.seen_more``), the
settled apples the harvest does not know (:func:`~picking_core.harvest.new_apples`: one the arm hid at home, one
behind an apple just picked) join the apples it has not started: the rest is planned again from the box after the
apple in hand (the first that ends ``lead`` s after the frame that showed them: planning) and spliced there. With
``follow=False`` the harvest keeps its first plan (what the camera showed at home, and nothing after). The arm
follows its schedule exactly (the servo's lag is the simulator's, not this playback's).

In the wind (``aim=True``) each apple the fruit map sees swaying is aimed where it will be when the fingers close,
and ridden (:meth:`Harvest.plan <picking_core.harvest.Harvest.plan>`'s ``follows``: a plan's first apple): the
first plan from the fits at home, and ``reaim`` s before each apple in hand is dropped the rest is planned again
from the fits then, so that every prediction looks only one approach ahead, as the planner does.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass

import numpy as np

from picking_core.fruit import Fate
from picking_core.fruit_map import FruitMap
from picking_core.harvest import SETTLED, HarvestRun, new_apples

from .sway_pick import arm_at

#: The fates of the apples a camera sees (on the tree, in the fingers, falling), as picking-sim's camera does.
SEEN_FATES = (Fate.ON_TREE, Fate.GRASPED, Fate.HELD, Fate.FALLING)


@dataclass(frozen=True)
class SeenHarvest:
    """What the world counted (``counts``, :meth:`FruitWorld.counts`), ``duration`` s from the first move to home,
    the apples ``seen`` when it was planned, those ``taken_in`` as it ran, and ``skipped``, each ``(index, why)`` of
    the apples planned that no cycle could pick."""

    counts: dict
    duration: float
    seen: int
    taken_in: int
    skipped: tuple
    reaimed: int = 0


def harvest_seen(harvest, world, samples, camera, look=1.0, step=0.01, lead=0.3, follow=True, branches=None,
                 aim=False, reaim=0.2):
    """Harvest what ``camera`` (a :class:`~picking_core.camera.DepthCamera`) sees of ``world`` with ``harvest`` (a
    :class:`~picking_core.harvest.Harvest`; ``samples`` the world's view of the arm,
    :class:`~picking_sim.orchard.ArmSamples`; ``branches`` ``(ends (M, 2, 3), radii (M,))``, the scene's rods,
    which hide apples and inside which a detection is refused), stepping the world every ``step`` s; ``aim`` and
    ``reaim`` for swaying apples; see the module. Returns a :class:`SeenHarvest`; ValueError when the camera saw
    no apple at home."""
    ends, radii = branches if branches is not None else (np.empty((0, 2, 3)), np.empty(0))
    fruit_map = FruitMap(branches=(ends, radii) if len(ends) else None)
    home = np.asarray(harvest.home, float)
    rest = np.append(home, harvest.cycle.s.gripper_open)
    period, latency = 1.0 / camera.settings.rate, camera.settings.latency
    pending = collections.deque()                       # (handed over at, stamp, positions, covariances, diameters, scores)
    schedule, places, skipped, runs = [], {}, {}, []    # runs: HarvestRun, in the order they take over
    seen = taken = 0
    reaimed = set()                                     # the ends of the apples in hand the rest was aimed again by
    t_prev, t, end = 0.0, 0.0, np.inf
    while t < end:
        t = t_prev + period
        times = np.arange(t_prev + step, t + step / 2, step)
        q = np.array([arm_at(schedule, s, rest) for s in times])
        tools, openings, links = samples(q)
        world.observe(times, tools, openings, links, samples.radii, samples.names)
        pending.append((t + latency, t, *_frame(camera, world, links[-1], samples.radii, ends, radii)))
        t_prev = t
        while pending and pending[0][0] <= t + 1e-9:
            _, stamp, *frame = pending.popleft()
            fruit_map.update(stamp, *frame)
        if not schedule and t >= look:
            poses = fruit_map.grasp_poses()
            if not poses:
                raise ValueError('the camera saw no apple from home')
            seen = len(poses)
            places.update((i, T) for i, T in enumerate(poses))
            plan = harvest.plan((home, 0 * home, 0 * home), poses, follows=_follows(fruit_map, places, aim), t0=t)
            schedule, runs = [(t, plan.plan)], [HarvestRun(plan, t)]
            skipped.update((s.index, s.reason) for s in plan.skipped)
            end = t + plan.plan.duration
            continue
        if not follow or not schedule:
            continue
        again = _reaimed(harvest, runs[-1], t, lead, reaim, places, fruit_map, reaimed) if aim else None
        if again is not None:
            at, plan = again
            schedule = [(s, p) for s, p in schedule if s < at] + [(at, plan.plan)]
            runs.append(HarvestRun(plan, at, before=runs[-1]))
            skipped.update((s.index, s.reason) for s in plan.skipped)
            end = at + plan.plan.duration
            continue
        new = new_apples(fruit_map.grasp_poses(settled=SETTLED), [T[:3, 3] for T in places.values()],
                         harvest.cycle.s.box_position)
        if not new:
            continue
        more = list(enumerate(new, start=max(places) + 1))
        places.update(more)
        again = _rest(harvest, runs[-1], t + lead, places, more)
        if again is None:
            skipped.update((i, 'seen after the last apple was in hand') for i, _ in more)
            continue
        at, plan = again
        taken += len(more)
        schedule = [(s, p) for s, p in schedule if s < at] + [(at, plan.plan)]
        runs.append(HarvestRun(plan, at, before=runs[-1]))
        skipped.update((s.index, s.reason) for s in plan.skipped)
        end = at + plan.plan.duration
    return SeenHarvest(world.counts(), end - schedule[0][0], seen, taken, tuple(sorted(skipped.items())),
                       len(reaimed))


def _follows(fruit_map, places, aim):
    """The Follows of the apples of ``places`` (index: pose where it hangs) the map sees swaying now (none without
    ``aim``)."""
    if not aim:
        return {}
    follows = {i: fruit_map.follow(T[:3, 3]) for i, T in places.items()}
    return {i: f for i, f in follows.items() if f is not None}


def _reaimed(harvest, run, t, lead, reaim, places, fruit_map, reaimed):
    """``(at, HarvestPlan)``: the rest of ``run`` planned again at ``t`` from the map's fits, when the apple in hand
    (at ``t + lead``) is dropped within ``reaim`` s of that and the next apple sways; None otherwise, and when no
    apple of the rest can be planned (the harvest runs on as planned, as the planner's does). Each apple in hand's
    end (kept in ``reaimed``) aims the rest once."""
    start, plan = run.start, run.plan
    k = next((j for j, a in enumerate(plan.apples) if start + a.end >= t + lead), None)
    if k is None or k + 1 >= len(plan.apples) or start + plan.apples[k].end > t + lead + reaim:
        return None
    at = round(start + plan.apples[k].end, 6)
    if at in reaimed or fruit_map.follow(places[plan.apples[k + 1].index][:3, 3]) is None:
        return None
    reaimed.add(at)
    left = [a.index for a in plan.apples[k + 1:]]
    q = plan.plan.trajectory.sample([plan.apples[k].end])[0][0]
    arm = q[:harvest.arm.dof]
    follows = _follows(fruit_map, {i: places[i] for i in left}, True)
    try:
        return at, harvest.plan((arm, 0 * arm, 0 * arm), [places[i] for i in left], gripper_start=float(q[-1]),
                                indices=left, follows=follows, t0=at)
    except ValueError:
        return None


def _rest(harvest, run, soonest, places, more):
    """``(at, HarvestPlan)``: the apples of ``run`` (a :class:`~picking_core.harvest.HarvestRun`) not started when
    the arm next rests in the box with no apple in hand from ``soonest`` (s), as the planner's runner finds it
    (``HarvestRun.in_the_box_after``), and ``more`` (``(index, pose)`` pairs), planned from rest in the box there;
    None once the last apple is in hand."""
    found = run.in_the_box_after(soonest)
    if found is None:
        return None
    (at, in_hand), start, plan = found, run.start, run.plan
    left = [a.index for a in plan.apples if start + a.start >= at - 1e-9] + [i for i, _ in more]
    q = plan.plan.trajectory.sample([in_hand])[0][0]
    arm = q[:harvest.arm.dof]
    return at, harvest.plan((arm, 0 * arm, 0 * arm), [places[i] for i in left], gripper_start=float(q[-1]),
                            indices=left)


def _frame(camera, world, links, link_radii, ends, radii):
    """One capture of ``world`` with the arm's ``links`` (capsules, ``link_radii``) and the branches hiding what
    they hide: ``(positions (N, 3), covariances (N, 3, 3), diameters (N,), scores (N,))`` in the arm's base."""
    present = np.isin(world.fate, SEEN_FATES)
    seen = camera.capture(world.p.copy(), world.radius, present, np.concatenate([ends, links]),
                          np.concatenate([radii, link_radii]))
    R, o = camera.mount[:3, :3], camera.origin
    positions = np.array([o + R @ d.position for d in seen]).reshape(-1, 3)
    covariances = np.array([R @ (np.eye(3) * d.sigma ** 2) @ R.T for d in seen]).reshape(-1, 3, 3)
    return positions, covariances, np.array([d.diameter for d in seen]), np.array([d.score for d in seen])
