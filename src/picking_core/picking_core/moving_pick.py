"""A pick of a moving apple (pure core): the grasp aimed where the apple will be when the fingers reach it.

A swaying apple is not where the camera last saw it: the camera's latency, the planning and the arm's approach put
the fingers' closing a second or more after the newest detection. :func:`aim` plans the pick cycle to the place the
apple's motion (:class:`~picking_core.sway.SwayFit`) predicts for the instant the planned fingers close to the
apple's width.

Planned again at each new detection (re-targets, spliced at the controller), the pick keeps its closing instant: the
move to P1 is stretched to arrive when the last plan said (Ruckig's least duration), and only the place is refined
as the prediction's horizon shrinks. Aiming each plan at the quickest closing instead chases the apple: every new
plan from a moving arm to a moved P1 takes a few tenths of a second again, so the closing never comes nearer. When
the arm cannot make the instant within ``SLIP`` (near P1, or the apple swung far), the running plan is kept: the aim
holds, as it does once the final straight approach has begun (a new plan would have to back out of it).

:func:`sure` is the closing rule: the fingers close only where the predicted centre, one standard deviation of the
prediction taken off (:func:`closing_margin`), stays inside their capture region. The prediction's
covariance holds the fit's own uncertainty (its frequency's too) and how far the apple strays from a steady sway: for
a steady sway one standard deviation of it is about the spread of the misses; a gust after the deciding aim is not
foreseen. The rule judges the aims that decide the closing
(:func:`holds_off`: the straight approach begins within ``DECIDE``); an earlier aim, a second or so ahead, is always
less sure and is refined by the detections still to come. A pick whose deciding aim is not sure goes to the stand-off
(P1) and holds there, aimed again at each detection, until an aim is sure (the pick then goes on from where the arm
is) or the pick cycle's ``hold_time`` has passed (it backs off home, never closing on air).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .fruit import Gripper

#: s: the closing instant is found to this step.
STEP = 1e-3
#: s: aim and plan agree when the plan's closing instant moves less than this between two rounds.
AGREE = 2e-3
#: Rounds of aiming at most (each plans the cycle once or twice).
ROUNDS = 4
#: s: the most a new plan may put the closing off (near P1 a new plan from the moving arm needs a slower line:
#: tenths of a second later, and the pursuit would never end).
SLIP = 0.02
#: m: the width a pick's fingers are timed to meet when the apple's own is not known (a typical apple's).
APPLE_WIDTH = 0.07
#: Standard deviations of the prediction the closing rule takes off the capture region.
SIGMAS = 1.0
#: s: an aim whose straight approach to the apple begins within this is the one the fingers close by.
DECIDE = 0.5
#: s of a swaying apple's prediction :meth:`Follow.reach` looks at (two periods of a 1 Hz sway).
SWAY_WATCH = 2.0


class AimHolds(ValueError):
    """No new plan closes on time: the running plan keeps its aim."""


@dataclass(frozen=True)
class Follow:
    """A pick's apple in motion: ``predict(t)`` is ``(mean, cov)`` of its centre at time ``t``; ``width``
    m; ``closes_at`` when the pick's last plan closes the fingers (None before one); times on the clock the apple's
    places are stamped with (the ROS clock), s; ``holding`` while the pick waits at the stand-off for a sure aim."""

    predict: Callable
    width: float = APPLE_WIDTH
    closes_at: float | None = None
    holding: bool = False

    def reach(self, centre, t, horizon=SWAY_WATCH):
        """``(extent, speed)``: how far the apple strays from ``centre`` (3,), m, and its fastest, m/s, over
        ``horizon`` s from time ``t`` as its prediction says (a steady sway shows both within a period)."""
        s = np.linspace(t, t + horizon, 201)
        p = np.array([self.predict(x)[0] for x in s])
        return (float(np.linalg.norm(p - np.asarray(centre, float), axis=1).max()),
                float(np.linalg.norm(np.diff(p, axis=0), axis=1).max() / (s[1] - s[0])))


def closing_time(plan, width):
    """s into ``plan`` (a pick cycle's, the gripper's opening its last joint) when the fingers have closed to
    ``width`` m: the instant they meet an apple that wide (its grasp's end if they never close that far)."""
    start, end = plan.extra['grasp_start'], plan.extra['grasp_end']
    t = np.arange(start, end + STEP, STEP)
    opening = plan.trajectory.sample(np.minimum(t, plan.duration))[0][:, -1]
    met = np.flatnonzero(opening <= width)
    return float(t[met[0]]) if len(met) else float(end)


@dataclass(frozen=True)
class Aim:
    """A pick aimed at a moving apple: its ``plan``, the grasp pose ``T`` it was planned to (4x4), ``at`` the plan's
    closing instant (s into it), and the prediction for that instant: ``mean`` (3,) and ``cov`` (3, 3), m (``mean``
    differs from ``T``'s place by what the last round of aiming left)."""

    plan: object
    T: np.ndarray
    at: float
    mean: np.ndarray
    cov: np.ndarray


def aim(plan_to, predict, rotation, width, at=None, slip=SLIP, ride=None):
    """The pick of an apple ``width`` m wide aimed where it will be: ``plan_to(T, approach_time)`` plans the cycle to
    grasp pose ``T`` with the move to P1 lasting at least ``approach_time`` s (None: as quick as it can);
    ``predict(s)`` is ``(mean, cov)`` of the apple's centre ``s`` s into the plan; ``rotation`` (3, 3) the grasp's;
    ``at`` s into the plan, the closing instant to keep (the last aim's; None: the soonest); ``ride(plan, motion,
    closes)`` (:meth:`~picking_core.pick_cycle.PickCycle.ride`), when given, makes the aimed plan's straight
    approach follow the predicted motion. None when no plan closes within ``slip`` s after ``at`` (the aim holds:
    the running plan is kept). Raises what ``plan_to`` raises."""
    soonest = at is None
    if soonest:
        at = closing_time(plan_to(grasp_pose(rotation, predict(0.0)[0]), None), width)
    for _ in range(ROUNDS):
        T = grasp_pose(rotation, predict(at)[0])
        plan = plan_to(T, None)
        closes = closing_time(plan, width)
        if closes < at - AGREE:                     # early: the move to P1 stretched to close on time
            plan = plan_to(T, _segment(plan, 'P1 approach').duration + at - closes)
            closes = closing_time(plan, width)
        if closes <= at + AGREE:
            break
        if not soonest and closes > at + slip:
            return None
        at = closes                                 # a little late: aimed again at that instant
    mean, cov = predict(closes)                     # where the apple will be when these fingers close
    if ride is not None:
        plan = ride(plan, lambda s: predict(s)[0], closes)
    return Aim(plan, T, closes, np.asarray(mean, float), np.asarray(cov, float))


def final_approach(plan):
    """s into a pick cycle's ``plan`` where its straight line to the apple begins (its grasp's start without one)."""
    return next((s.start for s in plan.segments if s.label == 'P2 to the apple'), plan.extra.get('grasp_start', np.inf))


def _segment(plan, label):
    return next(s for s in plan.segments if s.label == label)


def grasp_pose(rotation, p):
    """The 4x4 grasp pose turned by ``rotation`` (3, 3) at ``p`` (3,)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation, p
    return T


def closing_margin(a, gripper=Gripper(), sigmas=SIGMAS):
    """m: how far inside ``gripper``'s capture region (tool frame) the predicted centre of aim ``a`` lies at its
    closing instant, less ``sigmas`` standard deviations of the prediction along each axis; the least over the
    axes (negative: the fingers may close beside the apple)."""
    R = a.T[:3, :3]
    local = R.T @ (a.mean - a.T[:3, 3])
    sd = np.sqrt(np.maximum(np.diag(R.T @ a.cov @ R), 0.0))
    half = np.array([gripper.centred, gripper.across, gripper.along])
    return float(np.min(half - np.abs(local) - sigmas * sd))


def sure(a, gripper=Gripper()):
    """Whether aim ``a`` may close the fingers: its :func:`closing_margin` is not negative."""
    return closing_margin(a, gripper) >= 0.0


def holds_off(a, holding=False, begins=None):
    """Whether the pick of aim ``a`` goes to the stand-off instead: the aim decides the closing (the straight approach
    begins within :data:`DECIDE`: in ``begins`` s, else in ``a``'s plan's; or the pick already ``holding`` waits for a
    sure aim) and is not :func:`sure`."""
    begins = final_approach(a.plan) if begins is None else begins
    return (holding or begins <= DECIDE) and not sure(a)


def decide(plan_to, predict, rotation, width, at=None, holding=False, ride=None):
    """A pick's next plan as :func:`aim` makes it (same arguments; ``holding`` as :func:`holds_off` takes it):
    ``(aim, holds)``, the aim and whether the pick goes to the stand-off instead; None when the running plan keeps
    its aim. When no new plan keeps the closing instant, the running plan closes by the prediction all the same: the
    soonest aim from here says whether it is still sure enough to close on (else the pick holds off)."""
    aimed = aim(plan_to, predict, rotation, width, at, ride=ride)
    if aimed is not None:
        return aimed, holds_off(aimed, holding)
    soonest = aim(plan_to, predict, rotation, width)
    # (The running plan's straight approach begins about as long before its closing as the soonest plan's does.)
    if holds_off(soonest, holding, at - (soonest.at - final_approach(soonest.plan))):
        return soonest, True
    return None
