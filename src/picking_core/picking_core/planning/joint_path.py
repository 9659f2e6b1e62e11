"""A collision-free path in joint space between two configurations: bidirectional RRT-Connect, then
shortcutting (pure core). The path is waypoints; the pick cycle times it through them within the
limits with its own via-point methods.
"""

from __future__ import annotations

import numpy as np

#: rad: the longest step a tree grows by (largest joint change).
GROW = 0.25
#: rad: an edge is checked every this much of its largest joint change (a link end moves about a
#: centimetre then: the arm reaches about a metre).
EDGE_STEP = 0.01
#: Samples drawn toward the goal tree's root.
GOAL_BIAS = 0.1
#: Times a path's waypoints are doubled when the motion timed through them still cuts a corner into what the path
#: avoids (via points passed at speed round the corners of the clear polyline between them).
REFINE = 3


class NoPath(ValueError):
    """No collision-free path was found within the tries allowed."""


def _edge(a, b):
    """Samples of the straight joint-space segment ``a``-``b``, every EDGE_STEP rad of its largest joint change."""
    n = max(2, int(np.ceil(np.abs(b - a).max() / EDGE_STEP)) + 1)
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def clear_edge(colliding, a, b):
    """Whether the straight joint-space segment ``a``-``b`` is clear: ``colliding(q) -> (N,) bool``
    over samples every EDGE_STEP rad of its largest joint change."""
    return not colliding(_edge(a, b)).any()


def rrt_connect(colliding, start, goal, lower, upper, rng=None, iterations=600):
    """Waypoints (M, dof) from ``start`` to ``goal`` (both included) whose straight segments are all
    clear, within ``lower``..``upper`` (rad), shortcut; NoPath after ``iterations`` extensions without one."""
    rng = np.random.default_rng(0) if rng is None else rng
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if colliding(np.array([start, goal])).any():
        raise NoPath('the path\'s start or end itself is not clear')
    if clear_edge(colliding, start, goal):
        return np.array([start, goal])
    trees = [([start], [-1]), ([goal], [-1])]           # (nodes, parent index) from each end
    for i in range(iterations):
        grow, other = trees[i % 2], trees[1 - i % 2]
        target = other[0][0] if rng.random() < GOAL_BIAS else rng.uniform(lower, upper)
        new = _extend(colliding, grow, target)
        if new is None:
            continue
        # Connect: the other tree steps toward the new node until it reaches it or is blocked.
        while True:
            reached = _extend(colliding, other, grow[0][new])
            if reached is None:
                break
            if np.abs(other[0][reached] - grow[0][new]).max() < 1e-9:
                path = _trace(grow, new)[::-1] + _trace(other, reached)
                if i % 2:                               # grown from the goal's tree: reverse
                    path = path[::-1]
                return shortcut(colliding, np.array(path))
    raise NoPath(f'no collision-free joint path found in {iterations} extensions')


def _extend(colliding, tree, target):
    """Grow ``tree`` from its nearest node toward ``target`` by at most GROW; the new node's index, or
    None when that step is blocked."""
    nodes, parents = tree
    near = int(np.argmin(np.abs(np.asarray(nodes) - target).max(axis=1)))
    step = target - nodes[near]
    size = np.abs(step).max()
    new = target if size <= GROW else nodes[near] + step * (GROW / size)
    if not clear_edge(colliding, nodes[near], new):
        return None
    nodes.append(new)
    parents.append(near)
    return len(nodes) - 1


def _trace(tree, k):
    """The nodes from ``tree``'s node ``k`` back to its root."""
    nodes, parents = tree
    out = []
    while k >= 0:
        out.append(nodes[k])
        k = parents[k]
    return out


def shortcut(colliding, path):
    """``path`` with waypoints dropped: from each waypoint kept, straight on to the farthest later one
    whose segment is clear (every candidate segment checked in one call)."""
    path = np.asarray(path, float)
    kept = [0]
    while kept[-1] < len(path) - 1:
        i = kept[-1]
        farther = list(range(i + 2, len(path)))
        if not farther:
            kept.append(i + 1)
            continue
        samples = [_edge(path[i], path[j]) for j in farther]
        hit = colliding(np.concatenate(samples))
        ends = np.cumsum([len(x) for x in samples])
        clear = [j for j, a, b in zip(farther, ends - [len(x) for x in samples], ends) if not hit[a:b].any()]
        kept.append(max(clear) if clear else i + 1)
    return path[kept]


def doubled(points):
    """``points`` (M, dof) with the midpoint of each straight leg between them added."""
    out = np.empty((2 * len(points) - 1, points.shape[1]))
    out[::2] = points
    out[1::2] = 0.5 * (points[:-1] + points[1:])
    return out
