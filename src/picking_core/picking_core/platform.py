"""Several arms harvesting one tree (pure core, no ROS).

A :class:`Platform` is 2-4 arms at known base poses in a common ``platform`` frame, each with its own
box. The :class:`Coordinator` splits a tree's apples between them (each apple to an arm that reaches
it, by workspace, balanced by planned time), plans every arm's harvest with the same core the arm's
planner runs (:class:`~picking_core.harvest.Harvest`: given the same apples and start it plans the
same motion), and keeps the arms apart: the arms' collision capsules (from the URDF) are compared
over the planned trajectories, allowing for the arms' plans starting up to ``slack`` s apart, and a
conflict is settled by giving the apple to the other arm, by postponing it to a later round, or by
making one arm wait. What was settled how is in :attr:`Schedule.decisions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .harvest import Harvest, Skipped, synthetic_tree
from .kinematics import ArmModel, pose_matrix
from .kinematics.capsules import ArmCapsules, capsule_distances
from .pick_cycle import PickCycle, PickSettings
from .planning import Planner, PlannerSettings

#: m: no two arms' capsules come closer than this.
CLEARANCE = 0.05
#: s: two arms' plans are kept apart for any start of one up to this much before or after the other's.
SLACK = 0.25
#: s between the samples compared (the links' motion between samples is allowed for as well).
SAMPLE = 0.01
#: Conflicts settled per schedule before the apples still in conflict are left for a later round.
MAX_DECISIONS = 40


def harvest_from_parameters(arm, params):
    """A :class:`Harvest` of ``arm`` (an ArmModel) with the planner's parameters ``params`` (a dict by
    parameter name; the names that are not planning or pick-cycle settings are left out)."""
    planner = Planner(arm, PlannerSettings(**{k: v for k, v in params.items()
                                              if k in PlannerSettings.__dataclass_fields__}))
    pick = PickSettings(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in params.items()
                           if k in PickSettings.__dataclass_fields__}).validate(arm)
    return Harvest(PickCycle(planner, pick))


def load_harvest(urdf, parameter_files, **overrides):
    """:func:`harvest_from_parameters` for the arm in ``urdf`` with the settings of ``parameter_files``
    (ROS parameter YAML files of ``picking_planner``, later ones overriding earlier ones) and
    ``overrides`` (``box_position=[...]``)."""
    import yaml
    params = {}
    for path in parameter_files:
        params.update(yaml.safe_load(Path(path).read_text())['/**/picking_planner']['ros__parameters'])
    params.update(overrides)
    return harvest_from_parameters(ArmModel.from_urdf(urdf), params)


@dataclass(frozen=True)
class Mount:
    """One arm of a platform: its ROS namespace, its base pose in the platform frame (4x4) and the
    planner parameters it runs with beyond the shipped ones (its own ``box_position``)."""

    namespace: str
    base: np.ndarray
    params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Platform:
    """Arms sharing a tree. ``from_yaml`` reads ``picking_description/platforms/platform.yaml``'s layout."""

    arms: tuple
    frame: str = 'platform'

    @classmethod
    def from_dict(cls, d):
        arms = []
        for a in d.get('arms') or []:
            ns = str(a.get('namespace', '')).strip('/')
            if not ns:
                raise ValueError('every arm of the platform needs a namespace (arm1, arm2, ...)')
            xyz = np.asarray(a.get('xyz', [0, 0, 0]), float)
            rpy = np.radians(np.asarray(a.get('rpy_deg', [0, 0, 0]), float))
            if xyz.shape != (3,) or rpy.shape != (3,):
                raise ValueError(f'arm {ns}: xyz (m) and rpy_deg (deg) need 3 values each')
            T = np.eye(4)
            T[:3, :3] = Rotation.from_euler('xyz', rpy).as_matrix()
            T[:3, 3] = xyz
            arms.append(Mount(ns, T, dict(a.get('params') or {})))
        if not 1 <= len(arms) <= 8:
            raise ValueError(f'a platform has 1 to 8 arms, got {len(arms)}')
        if len({a.namespace for a in arms}) != len(arms):
            raise ValueError('two arms of the platform share a namespace')
        return cls(tuple(arms), str(d.get('frame', 'platform')))

    @classmethod
    def from_yaml(cls, path, layout=None):
        """The platform of ``path``; ``layout`` picks one of its ``layouts`` (default: its ``default``)."""
        import yaml
        d = yaml.safe_load(Path(path).read_text())
        layouts = d.get('layouts', {})
        name = layout or d.get('default')
        if name not in layouts:
            raise ValueError(f'{path}: no layout {name!r} (has {", ".join(layouts) or "none"})')
        return cls.from_dict(dict(layouts[name], frame=d.get('frame', 'platform')))

    def tree(self, n, seed=0, spacing=0.08):
        """A seeded synthetic tree of ``n`` apples (4x4 grasp poses in the platform frame) spanning the
        canopy in front of every arm: the single arm's tree (:func:`synthetic_tree`) widened along y."""
        ys = [a.base[1, 3] for a in self.arms]
        xs = [a.base[0, 3] for a in self.arms]
        low, high = np.array([0.55, -0.35, 0.40]), np.array([0.80, 0.35, 0.85])
        return synthetic_tree(n, seed, low + [min(xs), min(ys), 0], high + [max(xs), max(ys), 0], spacing)


def _wire(T):
    """``T`` as a planner receives it in a Pose (position and quaternion), so predictions match."""
    T = np.asarray(T, float)
    return pose_matrix(T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_quat())


#: Apples an arm's planner is sent at once: the next part goes out while the last apple of this one is in
#: hand, and the planner starts it when that apple is in the box (a harvest replacing one).
CHUNK = 25


@dataclass
class SharePlan:
    """An arm's share planned as its planner will plan it, part by part: ``chunks`` of ``(apples
    (tree indices, as sent), HarvestPlan (apples numbered as in the tree), start s from the share's
    start)``, each after the one before from the box where its last apple was dropped."""

    chunks: list

    @property
    def apples(self):
        """AppleTimes of every apple picked, s from the share's start, in picking order."""
        return tuple(replace(a, start=a.start + off, end=a.end + off)
                     for _, hp, off in self.chunks for a in hp.apples)

    @property
    def skipped(self):
        return tuple(x for _, hp, _ in self.chunks for x in hp.skipped)

    @property
    def duration(self):
        """s to the end of the last part (its way home)."""
        return self.chunks[-1][2] + self.chunks[-1][1].plan.duration if self.chunks else 0.0

    def sample(self, t):
        """Positions (arm joints and gripper) at times ``t`` (s from the share's start): each part until
        the next takes over; after the last, its end."""
        t = np.atleast_1d(np.asarray(t, float))
        offsets = np.array([off for _, _, off in self.chunks])
        which = np.clip(np.searchsorted(offsets, t, side='right') - 1, 0, len(self.chunks) - 1)
        q = None
        for w in np.unique(which):
            traj = self.chunks[w][1].plan.trajectory
            m = which == w
            part = traj.sample(np.clip(t[m] - offsets[w], 0.0, traj.duration))[0]
            if q is None:
                q = np.empty((len(t), part.shape[1]))
            q[m] = part
        return q

    def without_last(self):
        """The share without its last part (its apples then go to another arm)."""
        return SharePlan(self.chunks[:-1])


@dataclass
class ArmSchedule:
    """One arm's part: the tree's apples it is given (indices, in the order its planner gets them; the
    plan's ``apples`` are in picking order), its plan in its base frame (a HarvestPlan, None when it has
    none), and when the plan starts (s, the schedule's clock)."""

    mount: Mount
    apples: list
    plan: object = None
    start: float = 0.0
    #: A running arm's motion as released (``q(times)``, times on the schedule's clock): it is kept as it is.
    track: object = None

    @property
    def end(self):
        return self.start + (self.plan.duration if self.plan is not None else 0.0)


@dataclass
class Closest:
    """The closest approach of two arms: distance (m, less the links' motion between samples), when
    (s, the schedule's clock), which arms and which of their links."""

    distance: float = np.inf
    t: float = 0.0
    arms: tuple = ()
    links: tuple = ()

    def words(self):
        if not self.arms:
            return 'no two arms move together'
        return (f'{self.distance * 100:.1f} cm between {self.arms[0]} {self.links[0]} and {self.arms[1]} '
                f'{self.links[1]} at t = {self.t:.2f} s')


@dataclass
class Schedule:
    """A tree split and planned: per arm its :class:`ArmSchedule`, the apples no arm reaches
    (``skipped``), those left for a later round (``postponed``: they conflicted with another arm
    every way tried), the decisions that kept the arms apart (in words), the closest approach."""

    arms: list
    skipped: list
    postponed: list
    decisions: list
    closest: Closest

    @property
    def makespan(self):
        return max((a.end for a in self.arms if a.plan is not None), default=0.0)

    def picked(self):
        return sum(len(a.plan.apples) for a in self.arms if a.plan is not None)

    def apples_per_hour(self):
        return 3600.0 * self.picked() / self.makespan if self.makespan > 0 else 0.0


class Coordinator:
    """Splits a tree between a :class:`Platform`'s arms and plans them apart (see the module)."""

    def __init__(self, platform, harvests, clearance=CLEARANCE, slack=SLACK, sample=SAMPLE, chunk=CHUNK):
        if len(harvests) != len(platform.arms):
            raise ValueError('one Harvest per arm of the platform')
        self.platform, self.harvests = platform, list(harvests)
        self.capsules = [ArmCapsules.from_arm(h.arm) for h in harvests]
        self.clearance, self.slack, self.sample, self.chunk = clearance, slack, sample, chunk

    @classmethod
    def from_platform(cls, platform, harvest_for, **kwargs):
        """Each arm's Harvest made by ``harvest_for(**params)`` from the arm's own parameters."""
        return cls(platform, [harvest_for(**m.params) for m in platform.arms], **kwargs)

    # -- frames ------------------------------------------------------------------------------
    def in_base(self, k, apples):
        """The platform-frame ``apples`` (4x4) in arm ``k``'s base frame, as its planner receives them."""
        inv = np.linalg.inv(self.platform.arms[k].base)
        return [_wire(inv @ np.asarray(T, float)) for T in apples]

    # -- splitting ---------------------------------------------------------------------------
    def reach(self, apples, only=None):
        """For each arm, the apples (of ``only``, default all) it reaches: ``{index: (q at the approach,
        q above its box)}``."""
        only = list(range(len(apples))) if only is None else list(only)
        out = []
        for k, h in enumerate(self.harvests):
            ok, _ = h.reach(self.in_base(k, [apples[i] for i in only]))
            out.append({only[i]: (q1, q_top) for i, _, q1, q_top in ok})
        return out

    def split(self, apples, reach=None, only=None):
        """Each apple to an arm that reaches it: first the nearest arm (the workspaces stay apart), then
        apples at the edge of the busiest arm's share move to a less busy neighbour that reaches them,
        while that makes the busiest arm's estimated time shorter. Returns ``(shares, skipped)``."""
        reach = self.reach(apples, only) if reach is None else reach
        only = range(len(apples)) if only is None else only
        shares = [[] for _ in self.harvests]
        skipped = []
        bases = np.array([m.base[:3, 3] for m in self.platform.arms])
        cost = [self._apple_times(k, reach[k]) for k in range(len(self.harvests))]
        for i in only:
            T = apples[i]
            able = [k for k in range(len(reach)) if i in reach[k]]
            if not able:
                skipped.append(Skipped(i, 'no arm of the platform reaches it'))
                continue
            shares[min(able, key=lambda k: np.linalg.norm(bases[k] - np.asarray(T)[:3, 3]))].append(i)
        load = [sum(cost[k][i] for i in s) for k, s in enumerate(shares)]
        for _ in range(len(only)):
            busy = int(np.argmax(load))
            best = None
            for i in shares[busy]:
                for k in range(len(shares)):
                    if k == busy or i not in reach[k]:
                        continue
                    after = max(load[busy] - cost[busy][i], load[k] + cost[k][i])
                    # The apple nearest the other arm goes first: the shares stay side by side.
                    near = np.linalg.norm(bases[k] - np.asarray(apples[i])[:3, 3])
                    if after < load[busy] - 1e-9 and (best is None or (after, near) < best[:2]):
                        best = (after, near, i, k)
            if best is None:
                break
            _, _, i, k = best
            shares[busy].remove(i)
            shares[k].append(i)
            load[busy] -= cost[busy][i]
            load[k] += cost[k][i]
        return shares, skipped

    def _apple_times(self, k, reach_k):
        """Arm ``k``'s estimated time for each apple it reaches: the moves from above its box to the
        apple and back, plus the lines and dwells of a cycle (about as long again)."""
        if not reach_k:
            return {}
        idx = list(reach_k)
        q1 = np.array([reach_k[i][0] for i in idx])
        q_top = np.array([reach_k[i][1] for i in idx])
        times = self.harvests[k].cycle.planner.move_times
        go = np.diag(times(q_top, q1))
        return {i: 2.0 * g + 1.5 for i, g in zip(idx, go)}

    # -- planning and keeping apart ------------------------------------------------------------
    def _plan(self, k, apples_k, tree, start):
        """Arm ``k``'s :class:`SharePlan` of the tree's apples ``apples_k`` from ``start``, or None: the
        share in its best order, sent CHUNK apples at a time, each part planned as the arm's planner
        plans it (the first from ``start``, each next from the box, its apple in hand dropped)."""
        if not apples_k:
            return None
        h = self.harvests[k]
        local = self.in_base(k, [tree[i] for i in apples_k])
        ok, unreachable = h.reach(local)
        q0 = np.asarray(start[0], float)[:h.arm.dof]
        ordered, _, _ = h.order(ok, q0 if h.in_box(start) else h.home)
        route = [apples_k[a[0]] for a in ordered]
        chunks, state, gripper, offset = [], start, None, 0.0
        lost = [replace(x, index=apples_k[x.index]) for x in unreachable]
        for n in range(0, len(route), self.chunk):
            part = route[n:n + self.chunk]
            try:
                hp = h.plan(state, self.in_base(k, [tree[i] for i in part]), gripper_start=gripper)
            except ValueError as exc:
                lost += [Skipped(i, str(exc)) for i in part]
                continue
            hp = replace(hp, apples=tuple(replace(a, index=part[a.index]) for a in hp.apples),
                         skipped=tuple(replace(x, index=part[x.index]) for x in hp.skipped))
            chunks.append((part, hp, offset))
            # The next part starts where its planner will start it: in the box, the last apple dropped.
            last = hp.apples[-1]
            q = hp.plan.trajectory.state_at(last.end)[0]
            state = (q[:h.arm.dof].copy(), np.zeros(h.arm.dof), np.zeros(h.arm.dof))
            gripper, offset = float(q[-1]), offset + last.end
        if not chunks:
            return None
        if lost:
            _, hp, off = chunks[0]
            chunks[0] = (chunks[0][0], replace(hp, skipped=tuple(lost) + hp.skipped), off)
        return SharePlan(chunks)

    def samples(self, k, a, times, rest=None):
        """Arm ``k``'s capsules (in the platform frame) at ``times`` (s, the schedule's clock) as the
        :class:`ArmSchedule` ``a`` moves it; before and after its plan the arm rests at the plan's ends
        (with no plan, at ``rest`` or home)."""
        h = self.harvests[k]
        if a.track is not None:
            q = a.track(np.asarray(times))
        elif a.plan is None:
            q = np.broadcast_to(h.home if rest is None else rest, (len(times), h.arm.dof))
        else:
            q = a.plan.sample(np.asarray(times) - a.start)
        return self.capsules[k].segments(np.asarray(q)[:, :h.arm.dof], self.platform.arms[k].base)

    def closest(self, arms, horizon=None, rests=None):
        """The closest approach between every two of the :class:`ArmSchedule` s ``arms`` over the
        schedule (any start offset within ``slack``), and every time below the clearance, earliest first:
        ``(Closest, conflicts)`` with conflicts ``[(t, k, j, distance)]``. ``rests``: where each arm that
        has no plan stays (default: home)."""
        end = max([a.end for a in arms] + [0.0]) if horizon is None else horizon
        times = np.arange(0.0, end + self.sample, self.sample)
        rests = rests or [None] * len(arms)
        S = [self.samples(k, a, times, rests[k]) for k, a in enumerate(arms)]
        # How far any capsule end moves between two samples: allowed for on top of the clearance.
        moved = [np.r_[0.0, np.abs(np.diff(s, axis=0)).max(axis=(1, 2, 3)) * np.sqrt(3)] for s in S]
        best, conflicts = Closest(), []
        w = int(round(self.slack / self.sample))
        for k in range(len(arms)):
            for j in range(k + 1, len(arms)):
                d, t, pair, zero = self._apart(S[k], S[j], moved[k], moved[j], w, k, j)
                # The closest approach as planned (no start offset); the conflicts allow for any within the slack.
                if zero.any() and d[zero].min() < best.distance:
                    m = int(np.flatnonzero(zero)[np.argmin(d[zero])])
                    best = Closest(float(d[m]), float(times[t[m]]), (self.platform.arms[k].namespace,
                                   self.platform.arms[j].namespace),
                                   (self.capsules[k].links[pair[m][0]], self.capsules[j].links[pair[m][1]]))
                for m in np.flatnonzero(d < self.clearance):
                    conflicts.append((float(times[t[m]]), k, j, float(d[m])))
        conflicts.sort()
        return best, conflicts

    def _apart(self, A, B, moved_a, moved_b, w, k, j):
        """Distances between arm ``k``'s samples ``A`` and arm ``j``'s ``B`` shifted by up to ``w``
        samples either way, where their bounding boxes come within reach: ``(d, t, pairs, unshifted)``."""
        ra, rb = self.capsules[k].radius, self.capsules[j].radius
        lo_a = (A.min(axis=2) - ra[None, :, None]).min(axis=1)
        hi_a = (A.max(axis=2) + ra[None, :, None]).max(axis=1)
        lo_b = (B.min(axis=2) - rb[None, :, None]).min(axis=1)
        hi_b = (B.max(axis=2) + rb[None, :, None]).max(axis=1)
        n = len(A)
        margin = self.clearance + 0.05
        ia, ib, shift = [], [], []
        for s in range(-w, w + 1):
            a = np.arange(max(0, -s), min(n, n - s))
            b = a + s
            # Unshifted, every sample is measured: the closest approach is reported however far it is.
            near = s == 0 or np.all((lo_a[a] - margin <= hi_b[b]) & (lo_b[b] - margin <= hi_a[a]), axis=1)
            near = np.broadcast_to(near, a.shape)
            ia.append(a[near])
            ib.append(b[near])
            shift.append(np.full(near.sum(), s))
        ia, ib, shift = np.concatenate(ia), np.concatenate(ib), np.concatenate(shift)
        if not ia.size:
            return np.empty(0), np.empty(0, int), [], np.zeros(0, bool)
        d = capsule_distances(A[ia], ra, B[ib], rb)                      # (M, Ka, Kb)
        flat = d.reshape(len(ia), -1)
        m = flat.argmin(axis=1)
        dist = flat[np.arange(len(ia)), m] - 0.5 * (moved_a[ia] + moved_b[ib])
        pairs = [divmod(int(x), d.shape[2]) for x in m]
        # Report each conflict at the earlier of the two arms' sample times.
        return dist, np.minimum(ia, ib), pairs, shift == 0

    def schedule(self, tree, starts=None, shares=None, fixed=None, offsets=None, only=None):
        """Split ``tree`` (4x4 grasp poses in the platform frame) and plan every arm apart from the others.

        ``starts``: each arm's start state (default: at rest at home). ``fixed``: ``{k: ArmSchedule}`` of
        arms already running (their ``track``), kept as they are and given no apples. Conflicts are
        settled one at a time, earliest first, by whichever of these keeps the platform's last apple
        earliest: the apple in conflict to the other arm; postponed to a later round; the arm that came
        second waits until the other's apple is in the box. Returns a :class:`Schedule`.
        """
        tree = [np.asarray(T, float) for T in tree]
        fixed = fixed or {}
        if starts is None:
            starts = [(h.home, np.zeros(h.arm.dof), np.zeros(h.arm.dof)) for h in self.harvests]
        rests = [np.asarray(s[0], float) for s in starts]     # where an arm given no apples stays
        reach = self.reach(tree, only)
        later = set().union(*(reach[k] for k in fixed)) if fixed else set()
        for k in fixed:                                   # a running arm takes no apples
            reach[k] = {}
        postponed = []
        if shares is None:
            shares, skipped = self.split(tree, reach, only)
            # Apples only a running arm reaches wait for a later round.
            postponed = [s.index for s in skipped if s.index in later]
            skipped = [s for s in skipped if s.index not in later]
        else:
            skipped = []
        offsets = offsets or {}
        arms = [fixed[k] if k in fixed else ArmSchedule(m, list(s), start=offsets.get(k, 0.0))
                for k, (m, s) in enumerate(zip(self.platform.arms, shares))]
        for k, a in enumerate(arms):
            if k not in fixed:
                a.plan = self._plan(k, a.apples, tree, starts[k])
        skipped += self._given_on(arms, reach, tree, starts, fixed)
        self._balance(arms, reach, tree, starts, fixed)
        decisions = []
        for _ in range(MAX_DECISIONS):
            closest, conflicts = self.closest(arms, rests=rests)
            if not conflicts:
                break
            t, k, j, d = conflicts[0]
            options = self._options(arms, t, k, j, d, reach, tree, starts, fixed)
            if not options:
                break
            _, words, new_arms, new_postponed = min(options, key=lambda o: o[0])
            arms = new_arms
            postponed += new_postponed
            decisions.append(words)
        closest, conflicts = self.closest(arms, rests=rests)
        if conflicts:
            raise RuntimeError(f'arms still conflict after {len(decisions)} decisions: {closest.words()}')
        return Schedule(arms, sorted(skipped, key=lambda s: s.index), postponed, decisions, closest)

    def _balance(self, arms, reach, tree, starts, fixed, moves=8):
        """The split estimated the arms' times; planned, the arm that ends last gives its apple nearest a
        neighbour that ends earlier (and reaches it) to that neighbour, while the later of the two then
        ends earlier than it did."""
        bases = np.array([m.base[:3, 3] for m in self.platform.arms])
        for _ in range(moves):
            ends = [a.end if a.plan is not None and k not in fixed else -np.inf for k, a in enumerate(arms)]
            slow = int(np.argmax(ends))
            best = None
            for j in range(len(arms)):
                # (A neighbour that ends a cycle or more earlier; an arm with no plan ends at once.)
                if j == slow or j in fixed or max(ends[j], 0.0) > ends[slow] - 3.0:
                    continue
                for i in arms[slow].apples:
                    if i in reach[j]:
                        near = np.linalg.norm(bases[j] - tree[i][:3, 3])
                        if best is None or near < best[0]:
                            best = (near, i, j)
            if best is None:
                return
            _, i, j = best
            a = ArmSchedule(arms[slow].mount, [x for x in arms[slow].apples if x != i], None, arms[slow].start)
            b = ArmSchedule(arms[j].mount, arms[j].apples + [i], None, arms[j].start)
            a.plan = self._plan(slow, a.apples, tree, starts[slow])
            b.plan = self._plan(j, b.apples, tree, starts[j])
            if b.plan is None or i not in [x.index for x in b.plan.apples] or max(a.end, b.end) >= ends[slow] - 1e-6:
                return
            arms[slow], arms[j] = a, b

    def _given_on(self, arms, reach, tree, starts, fixed):
        """Apples an arm's plan skipped (a cycle that cannot be planned) go to another arm that reaches
        them; those no other arm can take are returned, skipped with the reason."""
        skipped = []
        for k, a in enumerate(arms):
            if a.plan is None or k in fixed:
                continue
            for s in a.plan.skipped:
                others = sorted((j for j in range(len(arms)) if j != k and j not in fixed and s.index in reach[j]),
                                key=lambda j: len(arms[j].apples))
                for j in others:
                    plan = self._plan(j, arms[j].apples + [s.index], tree, starts[j])
                    if plan is not None and s.index in [x.index for x in plan.apples]:
                        arms[j] = ArmSchedule(arms[j].mount, arms[j].apples + [s.index], plan, arms[j].start)
                        break
                else:
                    skipped.append(s)
            if a.plan.skipped:
                # The arm is sent only what it picks, and planned so: its planner plans what it is sent.
                picks = {x.index for x in a.plan.apples}
                arms[k] = ArmSchedule(a.mount, [i for i in a.apples if i in picks], None, a.start)
                arms[k].plan = self._plan(k, arms[k].apples, tree, starts[k])
        return skipped

    def _activity(self, a, t):
        """What arm schedule ``a`` does at ``t``: ``(apple times or None, since when)``."""
        if a.plan is None or t < a.start:
            return None, -np.inf
        for x in a.plan.apples:
            if a.start + x.start <= t < a.start + x.end:
                return x, a.start + x.start
        return None, a.start + (a.plan.apples[-1].end if a.plan.apples else 0.0)

    def _options(self, arms, t, k, j, d, reach, tree, starts, fixed):
        """The ways of settling the conflict of arms ``k`` and ``j`` at ``t`` that move the first conflict
        later: ``[(makespan, words, arms, postponed)]``."""
        since_k, since_j = self._activity(arms[k], t)[1], self._activity(arms[j], t)[1]
        # The arm that came second yields (an arm going home after its last apple cannot).
        y, o = (j, k) if since_j >= since_k else (k, j)
        (xy, _), (xo, _) = self._activity(arms[y], t), self._activity(arms[o], t)
        if xy is None or y in fixed:
            y, o, xy, xo = o, y, xo, xy
        if xy is None or y in fixed:
            return []
        ny, no = arms[y].mount.namespace, arms[o].mount.namespace
        what = f'{no} at apple {xo.index}' if xo is not None else f'{no} on its way'
        options = []

        def tried(new, words, post=()):
            c, conflicts = self.closest(new, rests=[np.asarray(x[0], float) for x in starts])
            if not conflicts or conflicts[0][0] > t + 1e-6:
                ms = max(a.end for a in new if a.plan is not None)
                options.append((ms + 60.0 * len(post), words, new, list(post)))

        def with_apples(k2, apples):
            a = ArmSchedule(arms[k2].mount, apples, self._plan(k2, apples, tree, starts[k2]), arms[k2].start)
            return a

        rest = [i for i in arms[y].apples if i != xy.index]
        if xy.index in reach[o]:
            new = list(arms)
            new[y] = with_apples(y, rest)
            new[o] = with_apples(o, arms[o].apples + [xy.index])
            tried(new, f'apple {xy.index} went from {ny} to {no}: {ny} would come within {d * 100:.1f} cm of {what} '
                       f'at t = {t:.1f} s')
        new = list(arms)
        new[y] = with_apples(y, rest)
        tried(new, f'apple {xy.index} of {ny} postponed to a later round: {ny} would come within {d * 100:.1f} cm of '
                   f'{what} at t = {t:.1f} s', [xy.index])
        if xo is not None:
            wait = arms[o].start + xo.end - (arms[y].start + xy.start) + self.slack
            if wait > 0:
                new = list(arms)
                new[y] = ArmSchedule(arms[y].mount, arms[y].apples, arms[y].plan, arms[y].start + wait)
                tried(new, f'{ny} waits {wait:.1f} s before its harvest for {what} (it would come within '
                           f'{d * 100:.1f} cm at t = {t:.1f} s)')
        return options
