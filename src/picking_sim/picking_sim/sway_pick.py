"""A pick of one swaying apple played through the fruit world (pure): how the planner's aim at a moving apple does by
the world's own count, for the tests and the benchmarks.

The world (:class:`~picking_core.fruit.FruitWorld`) sways the apple in its wind; a camera captures it at ``rate``
with ``noise`` and hands each detection over ``latency`` s after its stamp, as picking-sim's does; the planner's
side fits the sway (:class:`~picking_core.sway.SwayFit`) and plans the pick cycle. Each new plan starts ``lead`` s
after the detection that asked for it (planning and transport) and is spliced there onto the arm's schedule, as the
controller splices a re-target; the arm follows its schedule exactly (the servo's lag is the simulator's, not this
playback's). Three ways to aim:

- ``predicted``: where the fit says the apple will be when the fingers close (:func:`~picking_core.moving_pick.aim`),
  planned again at each detection until the final straight approach begins;
- ``latest``: the latest detection, planned again the same way (tracking without prediction);
- ``fixed``: the latest detection when the pick starts, never planned again (no tracking).
"""

from __future__ import annotations

import collections
from dataclasses import dataclass

import numpy as np

from picking_core.fruit import Fate
from picking_core.moving_pick import aim, closing_margin, final_approach
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
    last aim (None when not predicted); ``events``, the world's (:class:`~picking_core.fruit.Event`)."""

    in_box: bool
    bruised: bool
    knocks: int
    miss: float | None
    cycle: float
    plans: int
    margin: float | None
    events: tuple = ()


def pick_swaying(cycle, samples, world, index, rotation, mode, rate=30.0, latency=0.05, noise=0.003, watch=2.5,
                 lead=0.05, seed=0):
    """Pick apple ``index`` of ``world`` with ``cycle`` (a PickCycle; ``samples``: the world's view of the arm,
    :class:`~picking_sim.orchard.ArmSamples`) grasping along ``rotation`` (3, 3), aimed as ``mode`` says (see the
    module), after the camera watched it for ``watch`` s; returns a :class:`SwayPick`."""
    if mode not in MODES:
        raise ValueError(f'unknown mode {mode!r}: one of {", ".join(MODES)}')
    rng = np.random.default_rng(seed)
    fit, R = SwayFit(), np.eye(3) * noise ** 2
    width = 2 * float(world.radius[index])
    home = np.asarray(cycle.s.home_positions, float)
    rest = np.append(home, cycle.s.gripper_open)
    schedule = []                                   # (start s, plan), in the order they take over
    inbox = collections.deque()                     # (handed over at, stamp, detection)
    latest = last_aim = started = ends = miss = opening = None
    plans, events = 0, []
    dt = 1.0 / (rate * SUBSTEPS)
    for k in range(1, 10 ** 7):
        t = k * dt
        tools, openings, links = samples(_arm(schedule, t, rest)[None])
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

        def plan_to(T, approach_time=None, state=state, gripper=gripper):
            return cycle.plan(state, T, gripper, approach_time=approach_time)
        if mode == 'predicted':
            def predict(s, at=splice):
                return fit.predict(at + s)
        else:
            def predict(s, z=latest):
                return z, R
        aimed = aim(plan_to, predict, rotation, width, at)
        if aimed is None:
            continue                                # the aim holds: the running plan is kept
        last_aim, plan = aimed, aimed.plan
        plans += 1
        schedule = [(s, p) for s, p in schedule if s < splice] + [(splice, plan)]
        started = splice if started is None else started
    return SwayPick(bool(world.fate[index] == Fate.IN_BOX), bool(world.bruised[index]), int(world.knocks[index]),
                    miss, ends - started, plans,
                    closing_margin(last_aim) if mode == 'predicted' else None, tuple(events))


def _arm(schedule, t, rest):
    """The arm's joints and the gripper's opening at ``t`` on ``schedule`` (at rest before it begins)."""
    live = [(s, p) for s, p in schedule if s <= t]
    if not live:
        return rest
    begun, plan = live[-1]
    return plan.trajectory.sample([min(t - begun, plan.duration)])[0][0]

