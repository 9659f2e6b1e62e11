"""A planner that remembers its moves (pure core).

A pick cycle asks its planner for the same moves again and again: a cycle planned again with a
detour around a branch keeps its lines, its transfer and its way into the box; another approach to
the same apple, or the next apple of a harvest, goes into the box the same way. :class:`Remembered`
answers a move asked again with the same arguments from memory (the trajectory, or the refusal),
and asks the planner for everything else.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from ..kinematics import Unreachable

#: The planner's methods whose answers are remembered: each depends only on its arguments and the
#: planner's settings, and returns a trajectory (or a line's trajectory and path) never changed after.
REMEMBERED = ('line', 'arc', 'via', 'joint_move')
#: Answers kept, the least recently asked forgotten first (a harvest's cycles ask a few dozen each).
SIZE = 256


class Remembered:
    """``planner`` (a :class:`~picking_core.planning.Planner`) with the answers of its
    :data:`REMEMBERED` methods kept; every other attribute is the planner's own."""

    def __init__(self, planner, size=SIZE):
        self.planner, self.size = planner, size
        self._answers = OrderedDict()
        self.asked = self.answered = 0

    def __getattr__(self, name):
        method = getattr(self.planner, name)
        if name not in REMEMBERED:
            return method

        def remembered(*args, **kwargs):
            # The arguments themselves are kept with the answer: an object compared by identity
            # (a line's rest-to-rest timing) stays alive, so its id is not taken by another.
            key = (name, _key(args), _key(sorted(kwargs.items())))
            self.asked += 1
            if key in self._answers:
                self._answers.move_to_end(key)
                self.answered += 1
                answer, _ = self._answers[key]
            else:
                try:
                    answer = (True, method(*args, **kwargs))
                except (ValueError, Unreachable) as exc:
                    # Kept as its type and words: the exception itself holds the frames it passed
                    # (a reference cycle for the collector).
                    answer = (False, (type(exc), exc.args))
                self._answers[key] = (answer, (args, kwargs))
                if len(self._answers) > self.size:
                    self._answers.popitem(last=False)
            ok, value = answer
            if not ok:
                kind, words = value
                raise kind(*words)
            return value
        return remembered


def _key(x):
    """A hashable key of an argument: arrays by their bytes, containers by their items, numbers and
    strings as they are, anything else by identity."""
    if isinstance(x, np.ndarray):
        return ('array', x.dtype.str, x.shape, x.tobytes())
    if isinstance(x, (tuple, list)):
        return (type(x).__name__, tuple(_key(v) for v in x))
    if x is None or isinstance(x, (bool, int, float, str, np.number)):
        return x
    return ('object', id(x))
