"""The gripper on a GripperCommand action of its own, as ros2_controllers' gripper_action_controller serves it
(pure core): a command moves the gripper joint's reference to its target in a quintic within the joint's speed and
acceleration limits; the goal ends succeeded once the measured opening is within ``goal_tolerance`` of the target,
or, when the fingers stop short (an apple between them) for ``stall_timeout``, aborted with ``stalled`` (succeeded
with ``allow_stalling``). Once commanded, the channel owns the joint's reference: trajectories that leave the
gripper out do not move it; one that names it takes it back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from picking_core.trajectory import quintic

#: m the measured opening must move to count as moving (below: still, towards a stall).
STILL = 1e-4


@dataclass
class GripperAnswer:
    """How a command ended: ``word`` succeeded or aborted, where the fingers are, and why."""

    word: str
    position: float
    stalled: bool
    reached: bool


class GripperChannel:
    """The reference of joint ``index`` while a GripperCommand drives it."""

    def __init__(self, index, lower, upper, max_velocity, max_acceleration, goal_tolerance=0.01, stall_timeout=1.0,
                 allow_stalling=False):
        self.index, self.lower, self.upper = index, float(lower), float(upper)
        self.vmax = float(max_velocity) if np.isfinite(max_velocity) else 1.0
        self.amax = float(max_acceleration) if np.isfinite(max_acceleration) else 10.0
        self.goal_tolerance, self.stall_timeout, self.allow_stalling = goal_tolerance, stall_timeout, allow_stalling
        self.owns = False
        self.profile = None           # (start time, duration, the quintic) of the command running or last run
        self.target = None
        self._moved_at, self._last = None, None

    def command(self, target, now, current):
        """Move to ``target`` from ``current`` (the reference now); ValueError if it is beyond the joint's limits."""
        target = float(target)
        if not (np.isfinite(target) and self.lower - 1e-9 <= target <= self.upper + 1e-9):
            raise ValueError(f'gripper position {target} is beyond the joint\'s limits [{self.lower}, {self.upper}]')
        h = abs(target - current)
        # The quintic's peaks: 1.875 h / T within the speed limit, 5.77 h / T^2 within the acceleration limit.
        duration = max(1.875 * h / self.vmax, np.sqrt(5.7735 * h / self.amax), 1e-3)
        self.profile = (now, duration, quintic(current, target, duration))
        self.target, self.owns = target, True
        self._moved_at, self._last = now, None

    def release(self):
        """A trajectory that names the gripper takes its reference back."""
        self.owns = False

    def reference(self, now):
        """``(q, qd, qdd)`` of the gripper at ``now`` while the channel owns it, else None."""
        if not self.owns:
            return None
        start, duration, move = self.profile
        q, qd, qdd = move.state_at(min(max(now - start, 0.0), duration))
        return float(np.ravel(q)[0]), float(np.ravel(qd)[0]), float(np.ravel(qdd)[0])

    def judge(self, now, measured):
        """A running command's :class:`GripperAnswer` once it has ended at ``now`` (``measured`` opening), else None."""
        if self.target is None:
            return None
        if self._last is None or abs(measured - self._last) > STILL:
            self._last, self._moved_at = measured, now
        start, duration, _ = self.profile
        reached = abs(measured - self.target) <= self.goal_tolerance
        if reached and now >= start + duration:
            self.target = None
            return GripperAnswer('succeeded', measured, False, True)
        if now - self._moved_at >= self.stall_timeout and now >= start + duration:
            self.target = None
            return GripperAnswer('succeeded' if self.allow_stalling else 'aborted', measured, True, reached)
        return None

    def cancel(self, now, measured):
        """The running command is canceled: the fingers hold where they are."""
        self.command(min(max(measured, self.lower), self.upper), now, measured)
        self.target = None
