"""Goals as they come: the same goal sent again, and the one goal that waits (pure core)."""

from __future__ import annotations

from collections import OrderedDict

#: Goals remembered (with their answers) to know one sent again.
GOALS_KEPT = 1000
#: s after a goal in which the same goal again is a resend, not a new goal.
REPEAT_WINDOW = 30.0
#: s a goal waits for the first joint_states, or for a controller to serve its action, before it is refused.
WAIT_LIMIT = 5.0
#: The key of a topic goal stamped zero (as ``ros2 topic pub`` sends it): no identity of its own.
ZERO_KEY = '0.000000000'


class GoalBook:
    """The goals taken recently, by key, with their content and newest answer.

    A sender that hears no answer sends its goal again (a message published just as discovery completes
    can be lost): the same key with the same content within REPEAT_WINDOW s is that goal, answered again and
    not planned twice.
    """

    def __init__(self):
        self._goals = OrderedDict()      # key -> [content, answer, when it came (wall s)]

    def repeat(self, key, content, wall):
        """``(True, answer)`` when goal ``key`` with ``content`` (compared with ==) was taken already (the
        answer is None while it is still under way); ``(False, None)`` for a new goal, which is remembered."""
        if key == ZERO_KEY:
            return False, None
        seen = self._goals.get(key)
        if seen is not None and seen[0] == content and wall - seen[2] < REPEAT_WINDOW:
            return True, seen[1]
        self._goals[key] = [content, None, wall]
        self._goals.move_to_end(key)
        while len(self._goals) > GOALS_KEPT:
            self._goals.popitem(last=False)
        return False, None

    def answered(self, key, answer):
        """Keep the newest answer to goal ``key``, should the goal come again."""
        seen = self._goals.get(key)
        if seen is not None:
            seen[1] = answer


class Waiting:
    """The one goal that waits to be planned (for the arm's state, a controller, or the controller's answer to
    the plan before): a newer goal takes its place."""

    def __init__(self):
        self.goal = None

    def put(self, goal):
        """Let ``goal`` wait; returns the goal it replaces (to answer as superseded), or None."""
        old, self.goal = self.goal, goal
        return None if old is goal else old

    def take(self):
        goal, self.goal = self.goal, None
        return goal

    def expired(self, wall, ready):
        """The waiting goal when it waited more than WAIT_LIMIT s for what ``ready`` is not (taken), else None. A
        goal that waits only for the controller's answer to the plan before is never expired here: that answer
        is bounded by the lifecycle."""
        goal = self.goal
        if goal is not None and not ready and wall - goal.came > WAIT_LIMIT:
            self.goal = None
            return goal
        return None
