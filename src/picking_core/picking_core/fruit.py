"""Apples as bodies the simulator moves: the ground truth of what a harvest did (pure core).

Each apple is a sphere hanging from a stem pivot on a branch: a damped spherical pendulum whose length is
the stem's plus the apple's radius, pushed by wind. The world judges the arm from measured joint states
alone, never from what the planner meant:

- **grasp**: the gripper closing to the apple's width with its centre in the capture region between the
  fingers (:class:`Gripper`) holds it; closing with no apple there is a *missed grasp* of the nearest one;
- **detach**: a held apple pulled ``detach_stretch`` beyond its stem's length comes off the tree; opened
  before that, it swings back on its stem;
- **carry and drop**: a detached apple moves with the tool; opening the gripper releases it and it falls
  under gravity onto what is below: into the fruit box (*in the box*), onto another box of the scene or
  the ground (*dropped*, where);
- **knocks and bruises**: an arm link or a finger touching an apple not held is a *knock* (the apple is
  pushed aside, and may come off); a contact faster than ``bruise_speed`` (a landing in the lined box:
  ``box_bruise_speed``) is a *bruise*. (An apple in the fingers does not knock others: not modelled.)

Times are s, lengths m, in the arm's base frame (z up).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from .kinematics.capsules import point_segment_distances

GRAVITY = np.array([0.0, 0.0, -9.81])
#: s: the pendulums are integrated in steps no longer than this (an apple on a 3 cm stem swings at 2.4 Hz:
#: a sixtieth of its period keeps the symplectic step's period error near a tenth of a percent).
MAX_STEP = 0.01
#: m: a sample whose links are this far from every loose apple skips the contact check (apples move less
#: than that between two looks).
NEAR = 0.05
#: m an apple pushed aside by a link stays in that contact until this far from it (one knock, not one a sample).
CONTACT_HYSTERESIS = 0.01
#: m the fingers must close by to be a grasp (less is a drive settling at its set-point).
MIN_CLOSURE = 0.01
#: m the fingers open beyond an apple's width before it is let go.
RELEASE_MARGIN = 0.005


#: The gripper as apples feel it (tool frame, m; the URDF's visual geometry): two fingers 2 cm thick reaching
#: 6 cm back from the grasp point along z, on either side of it along x at the opening, and the wrist body
#: behind them, its round front 5 cm behind the grasp point where the URDF's cylinder ends (an apple held at the
#: grasp point does not touch it). (The URDF's collision capsules bound fingers and apple coarsely: what the
#: planner keeps clear of branches.)
FINGER_RADIUS, FINGER_LENGTH = 0.01, 0.06
WRIST = (np.array([0.0, 0.0, -0.15]), np.array([0.0, 0.0, -0.085]), 0.035)
#: m between the fingers where nothing says how far they are open (as for an approach).
OPEN = 0.09


class ArmBodies:
    """What of an arm touches apples: the links of ``capsules`` (an
    :class:`~picking_core.kinematics.capsules.ArmCapsules`) before the wrist's last joint, then the gripper's wrist
    body and two fingers at their opening (FINGER_RADIUS, FINGER_LENGTH, WRIST), with their ``radii`` and
    ``names``. One model for the simulator's world, which judges the touches, and the planner, which keeps its
    links off the apples still on the tree."""

    def __init__(self, capsules):
        self.capsules, self.arm = capsules, capsules.arm
        self.keep = np.flatnonzero(capsules.frame != self.arm.dof)      # the links before the wrist's last joint
        self.gripper_radii = np.array([WRIST[2], FINGER_RADIUS, FINGER_RADIUS])
        self.gripper_names = ['the wrist', 'a finger', 'a finger']
        self.radii = np.concatenate([capsules.radius[self.keep], self.gripper_radii])
        self.names = [capsules.links[k] for k in self.keep] + self.gripper_names

    def __call__(self, q, openings=None):
        """``(tools (N, 4, 4), links (N, K, 2, 3))``: the tool's poses and the bodies' segments at arm joint
        positions ``q`` (N, dof), the fingers ``openings`` (N,) apart (None: OPEN)."""
        q = np.atleast_2d(np.asarray(q, float))
        tools = self.arm.joint_frames(q)[:, -1]
        return tools, np.concatenate([self.capsules.segments(q)[:, self.keep], self.gripper(tools, openings)], axis=1)

    @staticmethod
    def gripper(tools, openings=None):
        """(N, 3, 2, 3): the wrist body's and the two fingers' segments with the tool at ``tools`` (N, 4, 4), the
        fingers ``openings`` (N,) apart (None: OPEN)."""
        openings = np.full(len(tools), OPEN) if openings is None else np.asarray(openings, float)
        x = openings / 2 + FINGER_RADIUS
        local = np.zeros((len(tools), 3, 2, 3))                            # wrist, finger +x, finger -x
        local[:, 0] = WRIST[:2]
        local[:, 1, :, 0], local[:, 2, :, 0] = x[:, None], -x[:, None]
        local[:, 1:, 0, 2] = -FINGER_LENGTH
        return np.einsum('nij,nkej->nkei', tools[:, :3, :3], local) + tools[:, None, None, :3, 3]


class Fate(enum.IntEnum):
    """Where an apple is."""

    ON_TREE = 0
    GRASPED = 1                   # in the fingers, still on its stem
    HELD = 2                      # off the tree, in the fingers
    FALLING = 3
    IN_BOX = 4
    DROPPED = 5

    @property
    def words(self):
        return self.name.lower().replace('_', ' ').replace('on tree', 'on the tree').replace('in box', 'in the box')


@dataclass(frozen=True)
class Gripper:
    """The capture region between the fingers, in the tool frame (tool0: the grasp point; the fingers
    close along its x axis and reach along its z axis): an apple whose centre is within ``across`` of
    tool0 along y (the fingers are 2 cm wide: half that and 1 cm of give), ``along`` along z (the
    fingers' 6 cm length, less the apple's curve: 2.5 cm either way) and ``centred`` along x (the
    fingers meet an apple off their middle by at most this much before they push it) is held when they
    close to its width."""

    across: float = 0.02
    along: float = 0.025
    centred: float = 0.02

    def captures(self, local):
        """Which centres ``local`` (N, 3, in the tool frame) are in the region."""
        local = np.asarray(local, float).reshape(-1, 3)
        return (np.abs(local[:, 0]) <= self.centred) & (np.abs(local[:, 1]) <= self.across) & \
            (np.abs(local[:, 2]) <= self.along)


@dataclass(frozen=True)
class FruitSettings:
    """How the world judges: ``detach_stretch`` (m pulled beyond the stem), ``bruise_speed`` (m/s: a
    contact with a link, the ground or a hard surface; an apple dropped from 5 cm lands at 1 m/s),
    ``box_bruise_speed`` (m/s onto the box's lining), ``damping`` (1/s, the stem's), ``miss_distance``
    (m: a closing this near an apple without holding it is a missed grasp of it), ``gripper``."""

    detach_stretch: float = 0.02
    bruise_speed: float = 1.0
    box_bruise_speed: float = 3.0
    damping: float = 1.5
    miss_distance: float = 0.10
    gripper: Gripper = field(default_factory=Gripper)


@dataclass(frozen=True)
class Wind:
    """A sway of ``amplitude`` m/s² (horizontal, along ``direction`` rad about z) at ``frequency`` Hz, each
    apple at its own phase, plus gusts (``gust_rate`` a second on average, each ``gust_strength`` m/s² at
    its peak for ``gust_time`` s, in a direction within 45 degrees of the wind's); ``seed`` fixes it all."""

    amplitude: float = 0.0
    frequency: float = 0.5
    direction: float = 0.0
    gust_rate: float = 0.0
    gust_strength: float = 0.0
    gust_time: float = 1.0
    seed: int = 0

    def __post_init__(self):
        for name in ('amplitude', 'frequency', 'gust_rate', 'gust_strength', 'gust_time'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f'wind {name} must be a finite number >= 0, got {value!r}')

    @property
    def still(self):
        return self.amplitude == 0.0 and (self.gust_rate == 0.0 or self.gust_strength == 0.0)

    def gusts(self, horizon):
        """``(starts, directions)`` of the gusts in the first ``horizon`` s."""
        rng = np.random.default_rng([self.seed, 1])
        if self.gust_rate <= 0.0 or self.gust_strength <= 0.0:
            return np.empty(0), np.empty((0, 3))
        n = rng.poisson(self.gust_rate * horizon)
        starts = np.sort(rng.uniform(0.0, horizon, n))
        yaw = self.direction + rng.uniform(-np.pi / 4, np.pi / 4, n)
        return starts, np.stack([np.cos(yaw), np.sin(yaw), np.zeros(n)], axis=1)

    def phases(self, n):
        return np.random.default_rng([self.seed, 2]).uniform(0.0, 2 * np.pi, n)


@dataclass
class Event:
    """Something that happened to apple ``index`` at ``t``: ``kind`` (grasped, detached, released on the tree,
    released, in the box, dropped, missed grasp, knocked, knocked off, bruised) at ``where``, in ``words``; a grasp's
    ``offset``: m from the grasp point to the apple's centre as the fingers took it."""

    t: float
    index: int
    kind: str
    where: np.ndarray
    words: str
    offset: float | None = None


class FruitWorld:
    """The apples of a tree: ``centres`` (N, 3) where they hang at rest, their ``radii`` (N,) and ``stems``
    (N,) lengths, m; ``box`` the fruit box's ``(lo, hi)`` (its inside), ``surfaces`` the tops an apple
    lands on elsewhere (``(name, lo, hi)`` each), ``ground_z``; ``wind``; ``t0`` the time it starts at.

    :meth:`observe` takes the arm's measured samples (tool pose, gripper opening, link capsules) and moves
    the apples to each sample's time, returning the :class:`Event`\\ s."""

    def __init__(self, centres, radii, stems, box, surfaces=(), ground_z=-np.inf, wind=Wind(),
                 settings=FruitSettings(), t0=0.0):
        self.rest = np.asarray(centres, float).reshape(-1, 3)
        n = len(self.rest)
        self.radius = np.broadcast_to(np.asarray(radii, float), (n,)).copy()
        self.stem = np.broadcast_to(np.asarray(stems, float), (n,)).copy()
        if not (np.all(np.isfinite(self.rest)) and np.all(self.radius > 0) and np.all(self.stem > 0)):
            raise ValueError('apples need finite centres and positive radii and stem lengths')
        self.length = self.stem + self.radius
        self.pivot = self.rest + np.array([0.0, 0.0, 1.0]) * self.length[:, None]
        self.p, self.v = self.rest.copy(), np.zeros((n, 3))
        self.fate = np.full(n, Fate.ON_TREE, int)
        self.bruised = np.zeros(n, bool)
        self.knocks = np.zeros(n, int)
        self.misses = np.zeros(n, int)
        self.landed = np.full((n, 3), np.nan)
        self.landed_on = [''] * n
        self.box = tuple(np.asarray(b, float) for b in box)
        self.surfaces = tuple((name, np.asarray(lo, float), np.asarray(hi, float)) for name, lo, hi in surfaces)
        self.ground_z = float(ground_z)
        self.wind, self.settings = wind, settings
        self.t = float(t0)
        self._t0 = float(t0)
        self._phase = wind.phases(n)
        self._gust_horizon = 0.0
        self._gusts = (np.empty(0), np.empty((0, 3)))
        self._grip = {}                  # apple index -> its centre in the tool frame while in the fingers
        self._opening = None
        self._closing = False            # the fingers closed at the last sample
        self._caught = False             # the closure under way caught an apple
        self._closed_from = 0.0          # the opening the closure under way started from
        self._touching = set()           # (apple, link) pairs in contact at the last sample
        self._links = None               # the last sample's capsule segments, for their speed
        self._tool = None                # the last sample's tool pose

    # -- what is where ------------------------------------------------------------------------------
    def __len__(self):
        return len(self.rest)

    def counts(self):
        """How many apples are where (``on_the_tree``, ``in_the_box``, ...), with the bruised, knocked and
        missed-grasp tallies."""
        out = {f.words.replace(' ', '_'): int(np.sum(self.fate == f)) for f in Fate}
        out.update(bruised=int(self.bruised.sum()), knocked=int(np.sum(self.knocks > 0)),
                   missed_grasps=int(self.misses.sum()))
        return out

    def wind_at(self, t):
        """The wind's acceleration on each apple at ``t`` (N, 3), m/s²."""
        w = self.wind
        n = len(self)
        if w.still:
            return np.zeros((n, 3))
        s = t - self._t0
        heading = np.array([np.cos(w.direction), np.sin(w.direction), 0.0])
        a = w.amplitude * np.sin(2 * np.pi * w.frequency * s + self._phase)[:, None] * heading
        if s > self._gust_horizon:
            self._gust_horizon = max(2 * self._gust_horizon, s + 60.0)
            self._gusts = w.gusts(self._gust_horizon)
        starts, dirs = self._gusts
        live = (starts <= s) & (s < starts + w.gust_time)
        if live.any():
            shape = np.sin(np.pi * (s - starts[live]) / w.gust_time)       # rises and falls over the gust
            a = a + w.gust_strength * (shape[:, None] * dirs[live]).sum(axis=0)
        return a

    # -- the arm's samples ----------------------------------------------------------------------------
    def observe(self, times, tools, openings, links, link_radii, link_names=None):
        """The arm at ``times`` (N,): ``tools`` (N, 4, 4) tool poses, ``openings`` (N,) finger openings (m),
        ``links`` (N, K, 2, 3) the capsule segments of its links and fingers, ``link_radii`` (K,), ``link_names``
        (K,) for the events. Returns the events."""
        events = []
        links, link_radii = np.asarray(links, float).reshape(len(times), -1, 2, 3), np.asarray(link_radii, float)
        names = list(link_names) if link_names is not None else [f'link {k}' for k in range(len(link_radii))]
        near = self._near(links, link_radii)
        for t, tool, opening, segs, pairs in zip(times, tools, openings, links, near):
            if t <= self.t:
                continue
            tool = np.asarray(tool, float)
            self._advance(float(t), tool, events)
            self._grasping(float(t), tool, float(opening), events)
            if len(pairs) or self._touching:
                self._knocks(float(t), segs, link_radii, names, pairs, events)
            self._links = (float(t), segs)
            self._tool = tool
        return events

    def finger_stop(self):
        """m: the opening the fingers cannot close past at the last sample: the width of the apple they hold, or of
        an apple on the tree whose centre is between them (the widest that fits between them: fingers already
        closed narrower push an apple aside, they are not pushed open); 0 with none (they close freely). A
        simulated gripper stops there, so that its measured opening tells a grasp from a closing on air."""
        if self._grip:
            return float(max(2 * self.radius[i] for i in self._grip))
        if self._tool is None:
            return 0.0
        local = (self.p - self._tool[:3, 3]) @ self._tool[:3, :3]
        between = (self.fate == Fate.ON_TREE) & self.settings.gripper.captures(local) & (2 * self.radius <= self._opening)
        return float(2 * self.radius[between].max()) if between.any() else 0.0

    def _near(self, links, link_radii):
        """Per sample of capsule segments ``links`` (N, K, 2, 3): the (apple, link) pairs within NEAR of each other
        at the batch's start (a falling apple is paired with every link)."""
        n_links = links.shape[1]
        falling = np.flatnonzero(self.fate == Fate.FALLING)
        always = [(int(i), k) for i in falling for k in range(n_links)]
        loose = np.flatnonzero(self.fate == Fate.ON_TREE)
        if not len(loose) or not len(links):
            return [always] * len(links)
        d = point_segment_distances(self.p[loose][None, :, None], links[:, None, :, 0], links[:, None, :, 1])  # (N, n, K)
        gap = d - link_radii[None, None] - self.radius[loose][None, :, None]
        out = [list(always) for _ in range(len(links))]
        for n, a, k in zip(*np.nonzero(gap < NEAR)):
            out[n].append((int(loose[a]), int(k)))
        return out

    def _advance(self, t, tool, events):
        """Every apple moved on to ``t``: on the tree a pendulum, in the fingers with the tool, falling under
        gravity until it lands."""
        dt_all = t - self.t
        steps = max(1, int(np.ceil(dt_all / MAX_STEP)))
        dt = dt_all / steps
        on_tree = self.fate == Fate.ON_TREE
        if self.wind.still:                      # an apple hanging still stays so
            on_tree &= (np.abs(self.v).max(axis=1) > 1e-9) | (np.abs(self.p - self.rest).max(axis=1) > 1e-9)
        falling = self.fate == Fate.FALLING
        for k in range(steps):
            tk = self.t + (k + 1) * dt
            if on_tree.any():
                a = GRAVITY + self.wind_at(tk)[on_tree] - self.settings.damping * self.v[on_tree]
                v = self.v[on_tree] + a * dt
                p = self.p[on_tree] + v * dt
                # The stem holds the apple at its length (a taut string: it may swing up, not stretch).
                d = p - self.pivot[on_tree]
                dist = np.linalg.norm(d, axis=1)
                taut = dist > self.length[on_tree]
                p[taut] = self.pivot[on_tree][taut] + d[taut] * (self.length[on_tree][taut] / dist[taut])[:, None]
                self.v[on_tree] = (p - self.p[on_tree]) / dt
                self.p[on_tree] = p
            if falling.any():
                for i in np.flatnonzero(falling):
                    before = self.p[i].copy()
                    self.v[i] = self.v[i] + GRAVITY * dt
                    self.p[i] = self.p[i] + self.v[i] * dt
                    if self._landing(i, before, tk, events):
                        falling[i] = False
        for i, local in self._grip.items():
            new = tool[:3, :3] @ local + tool[:3, 3]
            self.v[i] = (new - self.p[i]) / dt_all
            self.p[i] = new
            if self.fate[i] == Fate.GRASPED:
                stretch = np.linalg.norm(new - self.pivot[i]) - self.length[i]
                if stretch > self.settings.detach_stretch:
                    self.fate[i] = Fate.HELD
                    events.append(self._event(t, i, 'detached', 'came off the tree, held in the fingers'))
        self.t = t

    def _landing(self, i, before, t, events):
        """Apple ``i`` falling from ``before`` to its position now: True when it landed (in the box, or dropped
        on a surface or the ground)."""
        p, r = self.p[i], self.radius[i]
        speed = float(np.linalg.norm(self.v[i]))
        lo, hi = self.box
        over_box = np.all(p[:2] >= lo[:2]) and np.all(p[:2] <= hi[:2])
        if over_box and p[2] - r <= lo[2]:
            self.p[i, 2] = lo[2] + r
            return self._landed(i, t, Fate.IN_BOX, 'the fruit box', speed, self.settings.box_bruise_speed, events)
        if over_box and before[2] - r >= hi[2]:
            return False                 # into the box from above: on down to its floor
        if p[2] - r <= hi[2] and before[2] - r > hi[2] and np.all(p[:2] >= lo[:2] - r) and np.all(p[:2] <= hi[:2] + r):
            self.p[i, 2] = hi[2] + r
            return self._landed(i, t, Fate.DROPPED, "the fruit box's rim", speed, self.settings.bruise_speed, events)
        for name, slo, shi in self.surfaces:
            if np.all(p[:2] >= slo[:2]) and np.all(p[:2] <= shi[:2]) and p[2] - r <= shi[2] < before[2] - r:
                self.p[i, 2] = shi[2] + r
                return self._landed(i, t, Fate.DROPPED, name, speed, self.settings.bruise_speed, events)
        if p[2] - r <= self.ground_z:
            self.p[i, 2] = self.ground_z + r
            return self._landed(i, t, Fate.DROPPED, 'the ground', speed, self.settings.bruise_speed, events)
        return False

    def _landed(self, i, t, fate, on, speed, bruising, events):
        self.fate[i], self.v[i] = fate, 0.0
        self.landed[i], self.landed_on[i] = self.p[i], on
        kind = 'in the box' if fate == Fate.IN_BOX else 'dropped'
        events.append(self._event(t, i, kind, f'landed on {on} at {speed:.2f} m/s'))
        if speed > bruising:
            self._bruise(t, i, speed, f'landing on {on}', bruising, events)
        return True

    def _grasping(self, t, tool, opening, events):
        """The fingers at ``opening``: closing to an apple's width with its centre between them holds it;
        a closure that ends with nothing held is a missed grasp; opening lets go of what they hold."""
        before, self._opening = self._opening, opening
        if before is None:
            return
        for i in list(self._grip):
            if opening > 2 * self.radius[i] + RELEASE_MARGIN:
                del self._grip[i]
                if self.fate[i] == Fate.GRASPED:
                    self.fate[i] = Fate.ON_TREE
                    events.append(self._event(t, i, 'released on the tree', 'let go before it came off its stem'))
                else:
                    self.fate[i] = Fate.FALLING
                    events.append(self._event(t, i, 'released', 'let go: falling'))
        closing = opening < before - 1e-6
        if closing and not self._grip:
            local = (self.p - tool[:3, 3]) @ tool[:3, :3]
            caught = (self.fate == Fate.ON_TREE) & self.settings.gripper.captures(local) & (2 * self.radius >= opening)
            for i in np.flatnonzero(caught)[:1]:
                self._grip[int(i)] = local[i]
                self.fate[i] = Fate.GRASPED
                self._caught = True
                offset = float(np.linalg.norm(local[i]))
                events.append(self._event(t, int(i), 'grasped', f'the fingers closed on it at {opening * 100:.1f} cm, '
                                          f'its centre {offset * 1e3:.1f} mm from the grasp point', offset))
        if closing and not self._closing:            # a closure starts from the opening before
            self._closed_from = before
        if self._closing and not closing:            # a closure ended: a real one (not a drive's settling) caught?
            if not self._caught and self._closed_from - before >= MIN_CLOSURE:
                self._missed(t, tool, events)
            self._caught = False
        self._closing = closing

    def _missed(self, t, tool, events):
        d = np.linalg.norm(self.p - tool[:3, 3], axis=1)
        d[self.fate != Fate.ON_TREE] = np.inf
        if not len(d) or d.min() > self.settings.miss_distance:
            return
        i = int(np.argmin(d))
        self.misses[i] += 1
        local = (self.p[i] - tool[:3, 3]) @ tool[:3, :3]
        events.append(self._event(t, i, 'missed grasp', 'the gripper closed beside it: its centre '
                                  f'({local[0] * 100:.1f}, {local[1] * 100:.1f}, {local[2] * 100:.1f}) cm from the '
                                  'grasp point, outside the fingers'))

    def _knocks(self, t, segs, radii, names, pairs, events):
        """Links touching apples (of the candidate ``pairs`` and those touching at the last sample): each contact
        pushes the apple out of the link; its start is a knock."""
        touching = set()
        loose = (self.fate == Fate.ON_TREE) | (self.fate == Fate.FALLING)
        pairs = sorted({(i, k) for i, k in [*pairs, *self._touching] if loose[i]})
        if pairs:
            i_s, k_s = np.array(pairs).T
            gap = point_segment_distances(self.p[i_s], segs[k_s, 0], segs[k_s, 1]) - radii[k_s] - self.radius[i_s]
            for i, k, g in zip(i_s.tolist(), k_s.tolist(), gap):
                if g >= CONTACT_HYSTERESIS or (g >= 0.0 and (i, k) not in self._touching):
                    continue
                touching.add((i, k))
                if g >= 0.0:
                    continue             # still against the link, not in it
                speed = self._link_speed(t, segs, k)
                if (i, k) not in self._touching:
                    self.knocks[i] += 1
                    events.append(self._event(t, i, 'knocked', f'touched by {names[k]} at {speed:.2f} m/s'))
                    if speed > self.settings.bruise_speed:
                        self._bruise(t, i, speed, f'a knock by {names[k]}', self.settings.bruise_speed, events)
                if self._push_out(i, segs[k], radii[k], speed):
                    events.append(self._event(t, i, 'knocked off', f'{names[k]} tore it off its stem: falling'))
        self._touching = touching

    def _link_speed(self, t, segs, k):
        if self._links is None or t <= self._links[0]:
            return 0.0
        t0, before = self._links
        mid = segs[k].mean(axis=0) - before[k].mean(axis=0)
        return float(np.linalg.norm(mid) / (t - t0))

    def _push_out(self, i, seg, radius, speed):
        """Apple ``i`` pushed out of the link ``seg`` moving at ``speed``: True when that tore it off its stem."""
        a, b = seg
        ab = b - a
        s = np.clip(np.dot(self.p[i] - a, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0)
        closest = a + s * ab
        out = self.p[i] - closest
        n = np.linalg.norm(out)
        out = out / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
        self.p[i] = closest + out * (radius + self.radius[i])
        self.v[i] = out * speed
        if self.fate[i] == Fate.ON_TREE and \
                np.linalg.norm(self.p[i] - self.pivot[i]) - self.length[i] > self.settings.detach_stretch:
            self.fate[i] = Fate.FALLING
            return True
        return False

    def _bruise(self, t, i, speed, how, limit, events):
        if not self.bruised[i]:
            self.bruised[i] = True
            events.append(self._event(t, i, 'bruised', f'{how} at {speed:.2f} m/s (bruising above {limit:g} m/s)'))

    def _event(self, t, i, kind, words, offset=None):
        return Event(t, int(i), kind, self.p[i].copy(), f'apple {i}: {kind}: {words}', offset)

