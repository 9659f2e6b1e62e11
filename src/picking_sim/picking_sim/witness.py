"""The simulator as a witness: every contact of the measured arm with the scene, counted by a party
other than the planner that planned around it (pure core).

A contact is an episode: a link touching an obstacle (no clearance: a real touch), from the first
sample that touches until the first that does not. Each is reported when it starts (where, when)
and when it ends (how deep at worst, how long).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Episode:
    """One link touching one obstacle: from ``start`` (s) at ``point`` (m), ``depth`` its deepest (m,
    positive inside), ``end`` when it let go (None while it lasts)."""

    link: str
    obstacle: str
    start: float
    point: np.ndarray
    depth: float
    end: float = None

    def words(self):
        x, y, z = self.point
        where = f'{self.link} touches {self.obstacle} at ({x:.3f}, {y:.3f}, {z:.3f}) m'
        if self.end is None:
            return f'contact: {where}, {self.depth * 100:.1f} cm deep'
        return (f'contact ended: {where}, {self.depth * 100:.1f} cm deep at worst, for '
                f'{self.end - self.start:.3f} s')


class Witness:
    """Watches measured joint positions against a :class:`~picking_core.collision.CollisionChecker`
    (built with clearance 0 and no self-collision). ``observe`` returns the episodes that started or
    ended; ``count`` is how many have started."""

    def __init__(self, checker):
        self.checker = checker
        self.open = {}
        self.count = 0

    def observe(self, times, q):
        """Samples at ``times`` (s) of the arm's joints ``q`` (N, dof): the episodes begun or ended."""
        changed = []
        if not len(times):
            return changed
        for t, contacts in zip(times, self.checker.every_contact(np.asarray(q, float), times)):
            touching = set()
            for contact in contacts:
                key = (contact.link, contact.obstacle)
                touching.add(key)
                depth = max(0.0, -contact.distance)
                episode = self.open.get(key)
                if episode is None:
                    episode = self.open[key] = Episode(contact.link, contact.obstacle, float(t),
                                                       np.asarray(contact.point, float), depth)
                    self.count += 1
                    changed.append(episode)
                elif depth > episode.depth:
                    episode.depth, episode.point = depth, np.asarray(contact.point, float)
            for key in [k for k in self.open if k not in touching]:
                episode = self.open.pop(key)
                episode.end = float(t)
                changed.append(episode)
        return changed
