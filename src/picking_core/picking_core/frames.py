"""A tree of coordinate frames over time: the TF buffer, with no ROS in it.

Written to the semantics tf2 documents: every frame has one parent; the transform from a parent to a child
is kept over a time window (``cache_time``) and interpolated between stamps (linearly in translation,
spherically in rotation); a static transform holds at every time; a lookup between any two frames goes
through their common ancestor, at one time for the whole chain (0: the latest time every link of the chain
knows); and the errors are tf2's: a frame nobody published (:class:`UnknownFrame`), a time before or after
what the chain knows (:class:`ExtrapolationError`), frames in trees that do not connect
(:class:`Disconnected`), a cycle (:class:`CycleError`), and a transform that is not one (NaN, a zero
quaternion: :class:`InvalidTransform`). Times are s; translations m; quaternions x, y, z, w.

>>> buf = TransformBuffer()
>>> buf.set_transform('base_link', 'camera', [0.1, 0, 0.5], [0, 0, 0, 1], 0.0, static=True)
>>> buf.lookup('base_link', 'camera')[:3, 3]
array([0.1, 0. , 0.5])
"""

from __future__ import annotations

import bisect
import math
import threading

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

#: s of history kept per link (tf2's default buffer).
CACHE_TIME = 10.0


class LookupError_(LookupError):
    """Why a transform cannot be looked up (tf2's exception family)."""


class UnknownFrame(LookupError_):
    """A frame no transform names."""


class ExtrapolationError(LookupError_):
    """A time the chain does not know: before its oldest or after its newest transform."""


class Disconnected(LookupError_):
    """Two frames in trees that do not connect."""


class CycleError(LookupError_):
    """A frame that is its own ancestor."""


class InvalidTransform(ValueError):
    """A transform that is not one: non-finite, or a quaternion of zero length."""


class _Link:
    """The transforms of one child frame from its parent: times, translations, rotations (quaternions)."""

    __slots__ = ('parent', 'static', 'times', 'translations', 'rotations')

    def __init__(self, parent, static):
        self.parent, self.static = parent, static
        self.times, self.translations, self.rotations = [], [], []

    def add(self, t, translation, quaternion, cache_time):
        if self.static:
            self.times, self.translations, self.rotations = [t], [translation], [quaternion]
            return
        k = bisect.bisect_right(self.times, t)
        if k and self.times[k - 1] == t:             # the same stamp again: the newer value
            self.translations[k - 1], self.rotations[k - 1] = translation, quaternion
        else:
            self.times.insert(k, t)
            self.translations.insert(k, translation)
            self.rotations.insert(k, quaternion)
        cut = bisect.bisect_left(self.times, self.times[-1] - cache_time)
        if cut:
            del self.times[:cut], self.translations[:cut], self.rotations[:cut]

    def span(self):
        return (-math.inf, math.inf) if self.static else (self.times[0], self.times[-1])

    def at(self, t):
        """The 4x4 transform parent <- child at ``t`` (inside the span)."""
        if self.static or len(self.times) == 1:
            return _matrix(self.translations[-1], self.rotations[-1])
        k = bisect.bisect_right(self.times, t)
        if k == len(self.times):
            return _matrix(self.translations[-1], self.rotations[-1])
        t0, t1 = self.times[k - 1], self.times[k]
        w = (t - t0) / (t1 - t0)
        translation = (1 - w) * np.asarray(self.translations[k - 1]) + w * np.asarray(self.translations[k])
        rotations = Rotation.from_quat([self.rotations[k - 1], self.rotations[k]])
        quaternion = Slerp([0.0, 1.0], rotations)([w]).as_quat()[0]
        return _matrix(translation, quaternion)


def _checked(parent, child, translation, quaternion, stamp):
    """``(parent, child, translation, unit quaternion, stamp)`` as plain floats, or :class:`InvalidTransform` naming
    the frames (plain floats: a /tf message's transforms are taken many a second, numpy's per-call cost is not
    needed for seven numbers)."""
    parent, child = _frame(parent), _frame(child)
    what = f'the transform {parent} -> {child}'
    if not parent or not child:
        raise InvalidTransform(f'{what} names an empty frame')
    if parent == child:
        raise InvalidTransform(f'{what} makes {child!r} its own parent')
    try:
        tx, ty, tz = (float(v) for v in translation)
        qx, qy, qz, qw = (float(v) for v in quaternion)
        stamp = float(stamp)
    except (TypeError, ValueError):
        raise InvalidTransform(f'{what}: a translation is 3 numbers and a rotation 4, got {translation!r}, '
                               f'{quaternion!r}') from None
    if not all(map(math.isfinite, (tx, ty, tz, qx, qy, qz, qw, stamp))):
        raise InvalidTransform(f'{what} is not finite (translation {[tx, ty, tz]}, rotation {[qx, qy, qz, qw]}, '
                               f'stamp {stamp})')
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < 1e-9:
        raise InvalidTransform(f'{what} has a zero quaternion')
    return parent, child, (tx, ty, tz), (qx / norm, qy / norm, qz / norm, qw / norm), stamp


def _matrix(translation, quaternion):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
    T[:3, 3] = translation
    return T


class TransformBuffer:
    """Frames and the transforms between them over the last ``cache_time`` s; safe to use from several threads."""

    def __init__(self, cache_time=CACHE_TIME):
        self.cache_time = float(cache_time)
        self._links = {}
        self._lock = threading.Lock()

    def set_transform(self, parent, child, translation, quaternion, stamp, static=False):
        """The transform that takes a point in ``child`` to ``parent`` at time ``stamp`` (s); ``static``: at every
        time. Raises :class:`InvalidTransform` (the frames named) for non-finite values, a zero quaternion, a frame
        that is its own parent or an empty name."""
        refused = self.set_transforms([(parent, child, translation, quaternion, stamp)], static)
        if refused:
            raise refused[0]

    def set_transforms(self, rows, static=False):
        """Many transforms at once (a /tf message's): ``rows`` of ``(parent, child, translation, quaternion,
        stamp)``, each as for :meth:`set_transform`. The valid ones are taken; returns the :class:`InvalidTransform`
        of each one refused."""
        refused, taken = [], []
        for row in rows:
            try:
                taken.append(_checked(*row))
            except InvalidTransform as exc:
                refused.append(exc)
        with self._lock:
            for parent, child, translation, quaternion, stamp in taken:
                link = self._links.get(child)
                if link is None or link.parent != parent or link.static != bool(static):
                    link = self._links[child] = _Link(parent, bool(static))
                link.add(stamp, translation, quaternion, self.cache_time)
        return refused

    def frames(self):
        """Every frame the buffer knows (children and their parents)."""
        with self._lock:
            return sorted(set(self._links) | {link.parent for link in self._links.values()})

    def parent(self, frame):
        with self._lock:
            link = self._links.get(_frame(frame))
            return None if link is None else link.parent

    def can_transform(self, target, source, time=0.0):
        try:
            self.lookup(target, source, time)
        except LookupError_:
            return False
        return True

    def lookup(self, target, source, time=0.0):
        """The 4x4 transform that takes a point in frame ``source`` to frame ``target`` at ``time`` (s; 0: the latest
        time the whole chain knows). Raises a :class:`LookupError_` naming the frames and why."""
        target, source = _frame(target), _frame(source)
        with self._lock:
            up_source, up_target = self._chain(source), self._chain(target)
            root_source, root_target = (up_source[-1][0] if up_source else source), \
                (up_target[-1][0] if up_target else target)
            known = set(self._links) | {link.parent for link in self._links.values()}
            for frame in (target, source):
                if frame not in known:
                    raise UnknownFrame(f'frame {frame!r} does not exist (known: {", ".join(sorted(known)) or "none"})')
            if root_source != root_target:
                raise Disconnected(f'{source!r} and {target!r} are not in one tree: {source!r} hangs from '
                                   f'{root_source!r}, {target!r} from {root_target!r}')
            common = self._common(source, target, up_source, up_target)
            links_s = self._until(source, up_source, common)
            links_t = self._until(target, up_target, common)
            t = self._time(links_s + links_t, time, target, source)
            T_common_source = self._compose(links_s, t)
            T_common_target = self._compose(links_t, t)
        return np.linalg.inv(T_common_target) @ T_common_source

    # -- the tree ---------------------------------------------------------------------------------
    def _chain(self, frame):
        """``[(parent, link), ...]`` from ``frame`` up to its root; CycleError when it comes round."""
        out, seen = [], {frame}
        while (link := self._links.get(frame)) is not None:
            frame = link.parent
            if frame in seen:
                raise CycleError(f'the frames {" -> ".join(list(seen) + [frame])} form a cycle')
            seen.add(frame)
            out.append((frame, link))
        return out

    @staticmethod
    def _common(source, target, up_source, up_target):
        ancestors = [source] + [p for p, _ in up_source]
        of_target = {target} | {p for p, _ in up_target}
        return next(f for f in ancestors if f in of_target)

    @staticmethod
    def _until(frame, chain, common):
        """The links from ``frame`` up its ``chain`` to ``common`` (the frame's own first)."""
        out = []
        for parent, link in chain:
            if frame == common:
                break
            out.append((parent, link))
            frame = parent
        return out

    def _time(self, links, time, target, source):
        lo = max((link.span()[0] for _, link in links), default=-math.inf)
        hi = min((link.span()[1] for _, link in links), default=math.inf)
        if not time:
            return hi if math.isfinite(hi) else 0.0
        if time < lo - 1e-9:
            raise ExtrapolationError(f'{source!r} -> {target!r} at {time:.6f} s is {lo - time:.3f} s before the oldest '
                                     f'transform of the chain ({lo:.6f} s): extrapolation into the past')
        if time > hi + 1e-9:
            raise ExtrapolationError(f'{source!r} -> {target!r} at {time:.6f} s is {time - hi:.3f} s after the newest '
                                     f'transform of the chain ({hi:.6f} s): extrapolation into the future')
        return time

    @staticmethod
    def _compose(links, t):
        """parent_of_last <- ... <- first child, at ``t``."""
        T = np.eye(4)
        for _, link in links:
            T = link.at(t) @ T
        return T


def _frame(name):
    """A frame name as tf2 takes it: no leading slash."""
    return str(name).lstrip('/')
