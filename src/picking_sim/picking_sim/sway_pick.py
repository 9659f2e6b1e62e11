"""A pick of one swaying apple played through the fruit world (pure): how the planner's aim at a moving apple does by
the world's own count, for the tests and the benchmarks.

The world (:class:`~picking_core.fruit.FruitWorld`) sways the apple in its wind; a camera captures it at ``rate``
with ``noise`` and hands each detection over ``latency`` s after its stamp, as picking-sim's does; the planner's
side fits the sway (:class:`~picking_core.sway.SwayFit`) and plans the pick cycle. Each new plan starts ``lead`` s
after the detection that asked for it (planning and transport) and is spliced there onto the arm's schedule, as the
controller splices a re-target; the arm follows its schedule exactly (the servo's lag is the simulator's, not this
playback's). Three ways to aim:

- ``predicted``: where the fit says the apple will be when the fingers close (:func:`~picking_core.moving_pick.aim`),
  planned again at each detection until the final straight approach begins; an aim that decides the closing and is
  not sure of it (:func:`~picking_core.moving_pick.decide`) goes to the stand-off instead and waits there for a sure
  one, backing off home after the cycle's ``hold_time``, as the planner does;
- ``latest``: the latest detection, planned again the same way (tracking without prediction);
- ``fixed``: the latest detection when the pick starts, never planned again (no tracking).
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, replace

import numpy as np

from picking_core import trajectory
from picking_core.fruit import Fate
from picking_core.moving_pick import aim, closing_margin, decide, final_approach
from picking_core.sway import SwayFit

MODES = ('predicted', 'latest', 'fixed')
#: Simulation steps per camera frame (the world is observed at the frames' own instants).
SUBSTEPS = 10
#: s the arm rests at home after its plan ends before the playback stops (the apple lands).
SETTLE = 0.5


@dataclass(frozen=True)
class SwayPick:
    """What the world counted: the apple ``in_box``, ``bruised``, ``knocks``; ``miss`` m from the tool's grasp point to
    the apple's true centre when the fingers closed to its width (None: they never did); ``cycle`` s from the pick's
    start to the arm home again; ``plans`` made; ``margin`` m, the closing rule's (:func:`closing_margin`) for the
    last aim that closed (None when not predicted or none did); ``held`` s from the first plan to the stand-off to
    the pick's going on (or its backing off), 0 when it never waited; ``backed_off`` when it went home without
    closing; ``events``, the world's (:class:`~picking_core.fruit.Event`)."""

    in_box: bool
    bruised: bool
    knocks: int
    miss: float | None
    cycle: float
    plans: int
    margin: float | None
    held: float = 0.0
    backed_off: bool = False
    events: tuple = ()


def pick_swaying(cycle, samples, world, index, rotation, mode, rate=30.0, latency=0.05, noise=0.003, watch=2.5,
                 lead=0.05, seed=0, riding=True):
    """Pick apple ``index`` of ``world`` with ``cycle`` (a PickCycle; ``samples``: the world's view of the arm,
    :class:`~picking_sim.orchard.ArmSamples`) grasping along ``rotation`` (3, 3), aimed as ``mode`` says (see the
    module), after the camera watched it for ``watch`` s; ``riding``: aimed plans ride the apple
    (:meth:`~picking_core.pick_cycle.PickCycle.ride`) as the planner's do; returns a :class:`SwayPick`."""
    if mode not in MODES:
        raise ValueError(f'unknown mode {mode!r}: one of {", ".join(MODES)}')
    rng = np.random.default_rng(seed)
    fit, R = SwayFit(), np.eye(3) * noise ** 2
    width = 2 * float(world.radius[index])
    home = np.asarray(cycle.s.home_positions, float)
    rest = np.append(home, cycle.s.gripper_open)
    schedule = []                                   # (start s, plan), in the order they take over
    inbox = collections.deque()                     # (handed over at, stamp, detection)
    latest = last_aim = started = ends = miss = opening = hold_since = None
    plans, events, held, backed_off = 0, [], 0.0, False
    dt = 1.0 / (rate * SUBSTEPS)
    for k in range(1, 10 ** 7):
        t = k * dt
        tools, openings, links = samples(arm_at(schedule, t, rest)[None])
        events += world.observe([t], tools, openings, links, samples.radii, samples.names)
        if miss is None and opening is not None and openings[0] < opening and openings[0] <= width:
            miss = float(np.linalg.norm(world.p[index] - tools[0][:3, 3]))
        opening = openings[0]
        if k % SUBSTEPS == 0:
            inbox.append((t + latency, t, world.p[index] + rng.normal(0.0, noise, 3)))
        fresh = False
        while inbox and inbox[0][0] <= t + 1e-9:
            _, stamp, latest = inbox.popleft()
            fit.update(stamp, latest, R)
            fresh = True
        splice = t + lead
        if started is not None and ends is None:
            begun, current = schedule[-1]
            if mode == 'fixed' or splice - begun >= final_approach(current):
                ends = begun + current.duration      # the aim holds once the straight approach has begun
        if ends is not None:
            if t > ends + SETTLE:
                break
            continue
        if not fresh or (started is None and t < watch):
            continue
        if started is None:
            state, gripper, at = (home, 0 * home, 0 * home), None, None
        else:
            begun, current = schedule[-1]
            q, qd, qdd = (x[0] for x in current.trajectory.sample([min(splice - begun, current.duration)]))
            state, gripper = (q[:-1], qd[:-1], qdd[:-1]), float(q[-1])
            at = None if last_aim is None else last_aim.at - (splice - begun)

        def plan_to(T, approach_time=None, state=state, gripper=gripper, here=hold_since is not None):
            return cycle.plan(state, T, gripper, approach_time=approach_time, from_here=here, rides=riding)
        if mode == 'predicted':
            def predict(s, at=splice):
                return fit.predict(at + s)
        else:
            def predict(s, z=latest):
                return z, R
        if mode == 'predicted':
            decided = decide(plan_to, predict, rotation, width, at, hold_since is not None,
                             cycle.ride if riding else None)
        else:
            aimed = aim(plan_to, predict, rotation, width, at)
            decided = None if aimed is None else (aimed, False)
        if decided is None:
            continue                                # the aim holds: the running plan is kept
        aimed, holds = decided
        if holds:
            hold_since = splice if hold_since is None else hold_since
            held, last_aim = splice - hold_since, None
            backed_off = held >= cycle.s.hold_time
            plan = _opening_kept(cycle.back_off(state) if backed_off else cycle.stand_off(state, aimed.T),
                                 gripper if gripper is not None else cycle.s.gripper_open)
            if backed_off:
                ends = splice + plan.duration
        else:
            if hold_since is not None:
                held, hold_since = splice - hold_since, None
            last_aim, plan = aimed, aimed.plan
        plans += 1
        schedule = [(s, p) for s, p in schedule if s < splice] + [(splice, plan)]
        started = splice if started is None else started
    return SwayPick(bool(world.fate[index] == Fate.IN_BOX), bool(world.bruised[index]), int(world.knocks[index]),
                    miss, ends - started, plans,
                    closing_margin(last_aim) if mode == 'predicted' and last_aim is not None else None, held,
                    backed_off, tuple(events))


def _opening_kept(plan, opening):
    """``plan`` (the arm's joints only) with the fingers kept at ``opening``, as the controller keeps a joint a
    trajectory leaves out."""
    kept = trajectory.hold([opening], plan.duration)
    return replace(plan, trajectory=trajectory.stack([plan.trajectory, kept]))


def arm_at(schedule, t, rest):
    """The arm's joints and the gripper's opening at ``t`` on ``schedule`` (at rest before it begins)."""
    live = [(s, p) for s, p in schedule if s <= t]
    if not live:
        return rest
    begun, plan = live[-1]
    return plan.trajectory.sample([min(t - begun, plan.duration)])[0][0]

