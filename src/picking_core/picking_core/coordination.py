"""A tree harvested by a platform of arms, as it runs (pure core of ``picking-harvester``, no ROS).

:class:`PlatformRun` holds what the coordinator knows: the tree, each arm's share and the goals that
carry it, their statuses, the plans the arms' planners released (``planned_trajectory``) and the arms'
joint states. The node feeds it those messages and sends what it asks for: each arm's share, part by
part (the first part at the time the schedule gives the arm, each next one while the last apple of the
part before is in hand, so that the planner starts it from the box when that apple is dropped: a
harvest replacing one), and a stop when the arms' motions as released would come within the clearance.

Rounds: the first round splits the whole tree (:meth:`Coordinator.schedule
<picking_core.platform.Coordinator.schedule>`). An arm that is done takes the last part not yet
sent of the busiest arm; apples given back (an arm's fault or skip, or postponed by a conflict) are
harvested in further rounds: the open apples are split among the idle arms, planned apart from the
arms still running (their planned motion), and sent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .kinematics.capsules import capsule_distances
from .platform import ArmSchedule, Closest

#: s from sending a first part to its plan's start, as the planners time a first harvest (1.5 times
#: the planning time they expect), until an arm's own lead is seen.
LEAD = 3.0
#: s between the starts of the arms' first parts in a round: their planners plan and send one after
#: another instead of at once (a long plan reaching its controller after its start is planned again,
#: later).
STAGGER = 3.0
#: s after the last apple of a part comes in hand that the next part is sent (it must be planned and
#: delivered before that apple is in the box).
IN_HAND = 0.2
#: Times an apple is tried (given back after a fault, it is tried once more).
ATTEMPTS = 2
#: s a round's scheduling is first expected to take per apple (then as measured, twice over).
PLANNING = 0.3
#: Statuses of a goal's end.
FINAL = ('succeeded', 'refused', 'aborted', 'superseded', 'canceled')


def plural(n, word):
    """``n`` and ``word``, in the plural unless n is 1 ("1 part", "3 parts")."""
    return f'{n} {word}' + ('' if n == 1 else 's')


class Released:
    """An arm's motion as its planner released it: trajectories, each from its start on (a later one
    takes over at its start), the arm resting at the last point after the end."""

    def __init__(self):
        self.parts = []                  # (start s, times s from start, positions (n, dof))

    def add(self, start, times, positions):
        self.parts = [p for p in self.parts if p[0] < start] + [(float(start), np.asarray(times, float),
                                                                  np.asarray(positions, float))]

    @property
    def end(self):
        return self.parts[-1][0] + self.parts[-1][1][-1] if self.parts else -np.inf

    def q(self, t):
        """Positions at times ``t`` (s, absolute), linear between the points; None before any part."""
        t = np.atleast_1d(np.asarray(t, float))
        if not self.parts:
            return None
        out = np.empty((len(t), self.parts[0][2].shape[1]))
        starts = np.array([p[0] for p in self.parts])
        which = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, len(self.parts) - 1)
        for w in np.unique(which):
            s, times, q = self.parts[w]
            m = which == w
            rel = t[m] - s
            out[m] = np.stack([np.interp(rel, times, q[:, j]) for j in range(q.shape[1])], axis=1)
        return out


@dataclass
class ArmRun:
    """One arm of the run: its share (a SharePlan) and when it starts (s, absolute; the start seen
    in its first released plan once there is one), the parts sent (``goals``: status key -> the tree's
    apples in the goal's order) and the next to send, its picked apples, its state and motion."""

    namespace: str
    share: object = None
    start: float = np.nan
    sent_parts: int = 0
    goals: dict = field(default_factory=dict)
    last_goal: str = ''
    first_start: float = np.nan
    last_end: float = np.nan
    picked: list = field(default_factory=list)
    state: str = 'idle'                   # idle | waiting (its first part to send) | harvesting
    released: Released = field(default_factory=Released)
    sent_at: float = np.nan
    lead: float = LEAD                    # s from sending a first part to its plan's start, as last seen
    q: np.ndarray = None                  # the last joint state

    def unsent(self):
        """The tree's apples of the parts not sent yet."""
        return [i for part, _, _ in self.share.chunks[self.sent_parts:] for i in part] if self.share else []

    def pending(self):
        """The tree's apples given to this arm and not reported picked or given back."""
        return [i for ids in self.goals.values() for i in ids] + self.unsent()


class PlatformRun:
    """A platform's harvest of ``tree`` (4x4 grasp poses in the platform frame) with ``coordinator``;
    ``clock()`` gives the node's time, s."""

    def __init__(self, coordinator, tree, clock, lead=LEAD):
        self.c, self.tree, self.clock = coordinator, [np.asarray(T, float) for T in tree], clock
        self.arms = [ArmRun(m.namespace, lead=lead) for m in coordinator.platform.arms]
        self.t0, self.end = clock(), None
        self.planning = PLANNING                    # s an apple of a round takes to schedule, as last seen
        self.open = list(range(len(self.tree)))     # apples not in a box nor given up
        self.tries = np.zeros(len(self.tree), int)
        self.skipped = {}                           # index -> reason
        self.failed = []
        self.stopped = set()                        # arms being stopped for a motion too close to another
        self.stops = 0
        self.to_stop = []                           # (arm, why) for the node to stop
        self.decisions, self.rounds = [], 0
        self.planned = Closest()
        self.measured = Closest()
        self.events = []                            # (level, words) for the node to publish

    # -- rounds ---------------------------------------------------------------------------------
    def _round(self):
        """Split the open apples among the idle arms, apart from the running ones. The schedule's clock
        starts when the first parts, sent once it is ready, start to move (their lead after sending);
        a round that took longer to plan than allowed for is planned again."""
        idle = [k for k, a in enumerate(self.arms) if a.state == 'idle']
        busy = {i for a in self.arms if a.state != 'idle' for i in a.pending()}
        todo = [i for i in self.open if i not in busy]
        if not idle or not todo:
            return
        self.rounds += 1
        running = len(idle) < len(self.arms)
        lead = max(self.arms[k].lead for k in idle)
        for _ in range(3):
            t_plan = self.clock()
            # With arms running, the round is planned against their motion from when its parts can be
            # sent; with none, its clock starts once it is planned.
            ready = t_plan + 2.0 * self.planning * len(todo) if running else None
            try:
                schedule = self._schedule(todo, idle, (ready or t_plan) + lead)
            except RuntimeError as exc:           # no schedule kept the arms apart: those apples stay on the tree
                for i in todo:
                    self._give_up(i, f'no schedule kept the arms apart ({exc})')
                self.events.append(('WARN', f'round {self.rounds}: no schedule kept the arms apart ({exc}); '
                                            f'{len(todo)} apples left on the tree'))
                return
            self.planning = max((self.clock() - t_plan) / len(todo), 0.01)
            ready = self.clock() if ready is None else ready
            if self.clock() <= ready:
                break
        self.decisions += [f'round {self.rounds}: {d}' for d in schedule.decisions]
        if schedule.closest.distance < self.planned.distance:
            self.planned = schedule.closest
        for i in schedule.postponed:
            if not running:               # nothing will move out of its way: no later round would do better
                self._give_up(i, 'every way of picking it came within the clearance of another arm')
        for s in schedule.skipped:
            self._give_up(s.index, s.reason)
        given = []
        for k, a in enumerate(schedule.arms):
            if k not in idle or a.plan is None:
                continue
            arm = self.arms[k]
            arm.share, arm.sent_parts, arm.state = a.plan, 0, 'waiting'
            # Sent so as to start at its time, as long ahead as this arm's planner took the last time.
            arm.start = ready + lead + a.start
            arm.sent_at = arm.start - arm.lead
            given.append(f'{arm.namespace} {plural(len(a.plan.apples), "apple")} in {plural(len(a.plan.chunks), "part")}'
                         + (f' (starts {a.start:.1f} s after the first)' if a.start > 0 else ''))
        self.events.append(('OK', f'round {self.rounds}: ' + (', '.join(given) or 'no apple can be given')
                            + (f'; {len(schedule.postponed)} postponed' if schedule.postponed else '')
                            + f'; planned closest approach {schedule.closest.words()}'))
        for d in schedule.decisions:
            self.events.append(('OK', f'round {self.rounds}: {d}'))

    def _schedule(self, todo, idle, origin):
        """The round's schedule of the apples ``todo`` on the ``idle`` arms, its clock's 0 at ``origin``."""
        fixed = {k: ArmSchedule(self.c.platform.arms[k], [], a.share, a.start - origin)
                 for k, a in enumerate(self.arms) if k not in idle and a.share is not None}
        starts = []
        for k, a in enumerate(self.arms):
            h = self.c.harvests[k]
            q = h.home if a.q is None else np.asarray(a.q, float)[:h.arm.dof]
            starts.append((q, np.zeros(h.arm.dof), np.zeros(h.arm.dof)))
        offsets = {k: n * STAGGER for n, k in enumerate(idle)}
        return self.c.schedule(self.tree, starts, fixed=fixed, offsets=offsets, only=todo)

    def _take_over(self, k):
        """Arm ``k`` is done: the last part not sent of the arm with the most left goes back to the open
        apples (then a round gives them to the idle arms)."""
        donors = [a for a in self.arms if a.state == 'harvesting' and a.share is not None
                  and len(a.share.chunks) - a.sent_parts >= 1]
        if not donors:
            return
        donor = max(donors, key=lambda a: len(a.unsent()))
        part = donor.share.chunks[-1][0]
        donor.share = donor.share.without_last()
        self.decisions.append(f'{self.arms[k].namespace} takes over the last part of {donor.namespace} '
                              f'(apples {" ".join(map(str, part))})')
        self.events.append(('OK', self.decisions[-1]))

    # -- sending ---------------------------------------------------------------------------------------
    def due(self):
        """The parts to send now: ``[(arm, [(tree index, 4x4 in the arm's base frame)])]``. The first
        call plans the first round."""
        if self.rounds == 0:
            self._round()
        now = self.clock()
        out = []
        for k, a in enumerate(self.arms):
            if a.share is None or a.sent_parts >= len(a.share.chunks) or a.state == 'idle':
                continue
            if a.sent_parts == 0:
                due = a.sent_at
            else:
                # The next part goes once the last apple of the one before is in hand.
                prev_part, prev, off = a.share.chunks[a.sent_parts - 1]
                due = a.start + off + prev.apples[-1].start + IN_HAND
            if now + 1e-9 < due:
                continue
            part = a.share.chunks[a.sent_parts][0]
            if a.sent_parts == 0:
                a.state, a.sent_at = 'harvesting', now
            a.sent_parts += 1
            for i in part:
                self.tries[i] += 1
            out.append((k, list(zip(part, self.c.in_base(k, [self.tree[i] for i in part])))))
        return out

    def sent(self, k, key, apples):
        """Arm ``k``'s part of ``apples`` (tree indices) went out as goal ``key`` (its header stamp, as
        planner_status names it)."""
        self.arms[k].goals[key] = list(apples)
        self.arms[k].last_goal = key

    # -- what the arms say ------------------------------------------------------------------------
    def on_status(self, k, values, message):
        """A ``planner_status`` of arm ``k`` (its values as a dict)."""
        a, now = self.arms[k], self.clock()
        key = values.get('goal')
        if key not in a.goals:
            return
        ids = a.goals[key]
        state, apple = values.get('state'), values.get('apple')
        if apple is not None and apple.isdigit() and int(apple) < len(ids):
            i, word = ids[int(apple)], values.get('apple_state')
            if word == 'picked':
                self._picked(a, i)
            elif word == 'skipped':
                self.events.append(('WARN', f'{a.namespace} skipped apple {i}: {message.split(": ", 1)[-1]}'))
                self._retry(i, message)
            elif word in ('failed', 'missed'):
                self.events.append(('WARN', f'{a.namespace} {word} apple {i}: {message.split(": ", 1)[-1]}'))
                self.failed.append(i)
        if state not in FINAL:
            return
        for j in values.get('picked_apples', '').split():
            if j.isdigit() and int(j) < len(ids):
                self._picked(a, ids[int(j)])
        del a.goals[key]
        if state == 'superseded' and key != a.last_goal:
            return                        # its next part took over, as meant
        more = a.share is not None and a.sent_parts < len(a.share.chunks)
        if state != 'succeeded' or more:
            why = (f'its harvest {state}: {message}' if state != 'succeeded'
                   else 'its part ended before the next one came (the arm went home)')
            self.events.append(('WARN', f'{a.namespace}: {why}'))
            # The arm stopped short of its plan: the others were kept apart from a motion it no longer makes.
            if a.q is not None and state != 'succeeded':
                a.released.add(now, np.array([0.0, 1.0]), np.vstack([a.q, a.q]))
                for j, b in enumerate(self.arms):
                    if j != k and b.state == 'harvesting':
                        self._check(j, now)
            for i in ids + a.pending():
                if i in self.open and state == 'canceled' and k not in self.stopped:
                    self._give_up(i, f'{a.namespace}: its harvest was canceled (a stop)')
                elif i in self.open:
                    self._retry(i, f'{a.namespace}: {why}')
        self.stopped.discard(k)
        a.state, a.share, a.goals, a.last_end = 'idle', None, {}, now
        if state == 'succeeded' and not more:
            self._take_over(k)
        self._round()
        if self.finished():
            self.end = now

    def _picked(self, a, i):
        if i in self.open:
            self.open.remove(i)
            a.picked.append(i)
            self.events.append(('OK', f'{a.namespace}: apple {i} delivered ({self.picked()} of {len(self.tree)})'))

    def _retry(self, i, reason):
        if self.tries[i] >= ATTEMPTS:
            self._give_up(i, f'tried {self.tries[i]} times; last: {reason}')

    def _give_up(self, i, reason):
        if i in self.open:
            self.open.remove(i)
            self.skipped[i] = reason

    def on_released(self, k, start, times, positions):
        """Arm ``k``'s planner released a plan (``planned_trajectory``): kept as its motion. When it
        would come within the clearance of another arm's released motion, arm ``k`` is put on
        :attr:`to_stop` with the reason."""
        a = self.arms[k]
        a.released.add(start, times, positions)
        if a.state == 'harvesting' and a.share is not None:
            if a.sent_parts == 1:
                # Its first part (planned again if it came late): the share's clock is where it starts.
                if not np.isnan(a.sent_at):
                    a.lead, a.sent_at = start - a.sent_at, np.nan
                a.start = start
            else:
                # A next part starts when the last apple before it is in the box; if it started elsewhere
                # (planned again, later), the parts after it are timed from where it did.
                off = a.share.chunks[a.sent_parts - 1][2]
                if abs(start - (a.start + off)) > 1e-3:
                    self.events.append(('WARN', f'{a.namespace}: part {a.sent_parts} started '
                                                f'{start - a.start - off:+.3f} s from its planned time'))
                    a.start = start - off
            if np.isnan(a.first_start) or a.sent_parts == 1 and not a.picked:
                a.first_start = start          # (its first plan again, if that came late)
        self._check(k, start)

    def _check(self, k, since):
        """Arm ``k``'s released motion from ``since`` against every other arm's: stop it if they meet."""
        a = self.arms[k]
        worst = Closest()
        for j, b in enumerate(self.arms):
            if j == k or not b.released.parts:
                continue
            t = np.arange(since, max(a.released.end, b.released.end, since) + self.c.sample, self.c.sample)
            A = self.c.capsules[k].segments(a.released.q(t)[:, :self.c.harvests[k].arm.dof], self.c.platform.arms[k].base)
            B = self.c.capsules[j].segments(b.released.q(t)[:, :self.c.harvests[j].arm.dof], self.c.platform.arms[j].base)
            d = capsule_distances(A, self.c.capsules[k].radius, B, self.c.capsules[j].radius)
            m = np.unravel_index(np.argmin(d), d.shape)
            if d[m] < worst.distance:
                worst = Closest(float(d[m]), float(t[m[0]] - self.t0), (a.namespace, b.namespace),
                                (self.c.capsules[k].links[m[1]], self.c.capsules[j].links[m[2]]))
        if worst.distance < self.c.clearance and a.state == 'harvesting' and k not in self.stopped:
            why = f'its motion would come within {worst.words()}'
            self.stopped.add(k)
            self.stops += 1
            self.decisions.append(f'{a.namespace} stopped: {why}')
            self.to_stop.append((k, why))

    def on_joint_state(self, k, q, now=None):
        """Arm ``k``'s joint state (measured at ``now``, s; default: the clock's time): the closest
        approach measured between the arms."""
        now = self.clock() if now is None else now
        self.arms[k].q = np.asarray(q, float)
        A = None
        for j, b in enumerate(self.arms):
            if j == k or b.q is None:
                continue
            if A is None:
                A = self.c.capsules[k].segments(self.arms[k].q[None, :self.c.harvests[k].arm.dof],
                                                self.c.platform.arms[k].base)
            B = self.c.capsules[j].segments(b.q[None, :self.c.harvests[j].arm.dof], self.c.platform.arms[j].base)
            d = capsule_distances(A, self.c.capsules[k].radius, B, self.c.capsules[j].radius)[0]
            m = np.unravel_index(np.argmin(d), d.shape)
            if d[m] < self.measured.distance:
                self.measured = Closest(float(d[m]), now - self.t0, (self.arms[k].namespace, b.namespace),
                                        (self.c.capsules[k].links[m[0]], self.c.capsules[j].links[m[1]]))
            if d[m] < self.c.clearance:
                # The arms run off their plans' clocks (a stalled controller carries on later): both stop.
                for x in (k, j):
                    arm = self.arms[x]
                    if arm.state == 'harvesting' and x not in self.stopped:
                        self.stopped.add(x)
                        self.stops += 1
                        why = f'measured {d[m] * 100:.1f} cm from {self.arms[j if x == k else k].namespace}'
                        self.decisions.append(f'{arm.namespace} stopped: {why}')
                        self.to_stop.append((x, why))

    # -- the run's end --------------------------------------------------------------------------------
    def picked(self):
        return sum(len(a.picked) for a in self.arms)

    def faulted(self):
        """The apples left on the tree for a fault (tried as often as allowed, or a stop), not for reach."""
        return sorted(i for i, why in self.skipped.items() if why.startswith('tried') or 'canceled' in why)

    def finished(self):
        return all(a.state == 'idle' for a in self.arms) and not self.open

    def summary(self):
        """The run's figures: apples picked (per arm and in all), apples per hour per arm and in all
        (from the first plan's start), the closest approaches planned and measured, the rounds and
        decisions, the apples left with the reason."""
        now = self.clock()
        end = self.end if self.end is not None else now
        starts = [a.first_start for a in self.arms if not np.isnan(a.first_start)]
        began = min(starts) if starts else self.t0
        took = end - began
        per_arm = {}
        for a in self.arms:
            busy = (a.last_end if not np.isnan(a.last_end) else now) - a.first_start
            per_arm[a.namespace] = dict(picked=len(a.picked), harvest_time=busy if a.picked else 0.0,
                                        apples_per_hour=3600.0 * len(a.picked) / busy if a.picked and busy > 0
                                        else 0.0)
        return dict(apples=len(self.tree), picked=self.picked(), harvest_time=took, wall_time=end - self.t0,
                    apples_per_hour=3600.0 * self.picked() / took if took > 0 else 0.0, arms=per_arm,
                    rounds=self.rounds, decisions=list(self.decisions), left=dict(self.skipped),
                    closest_planned=self.planned.distance, closest_planned_words=self.planned.words(),
                    closest_measured=self.measured.distance, closest_measured_words=self.measured.words())

    def words(self):
        s = self.summary()
        arms = ', '.join(f'{ns} {v["picked"]} ({v["apples_per_hour"]:.0f}/h)' for ns, v in s['arms'].items())
        return (f'{s["picked"]} of {s["apples"]} apples picked in {s["harvest_time"]:.1f} s, '
                f'{s["apples_per_hour"]:.0f} apples/h ({arms}); closest approach between arms: planned '
                f'{s["closest_planned_words"]}, measured {s["closest_measured_words"]}')
