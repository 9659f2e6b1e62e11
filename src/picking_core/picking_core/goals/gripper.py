"""The gripper as an action of its own (a ``control_msgs/GripperCommand`` server, as ros2_controllers'
gripper_action_controller serves it), beside the arm's FollowJointTrajectory: when a plan moves the fingers,
the commands a flight sends at those times, and what their answers mean.

A plan carries the finger opening as one more column (:data:`~picking_core.pick_cycle.GRIPPER_JOINT`). A
controller that drives the gripper as one of its joints takes it so; a standard arm controller knows only the
arm's joints, so the column is taken out of the trajectory and turned into commands: one at the start of each
move of the opening, to the opening where that move ends (:func:`gripper_moves`). A flight's commands not yet
sent are dropped when a newer plan takes over before their time, or the flight is canceled.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: m (or the gripper's unit): a change of the opening column smaller than this is no move.
STILL = 1e-6


def gripper_moves(times, openings):
    """``[(t, target), ...]``: where the opening column (``openings`` at the plan's point ``times``, s) starts
    each move, and the opening that move ends at."""
    times, openings = np.asarray(times, float), np.asarray(openings, float)
    moves, i, n = [], 1, len(times)
    while i < n:
        if abs(openings[i] - openings[i - 1]) <= STILL:
            i += 1
            continue
        j = i
        while j + 1 < n and abs(openings[j + 1] - openings[j]) > STILL:
            j += 1
        moves.append((float(times[i - 1]), float(openings[j])))
        i = j + 1
    return moves


@dataclass
class GripperCommand:
    """One command of a flight: sent at schedule time ``at`` (s), to ``target``; its answer once it came."""

    at: float
    target: float
    sent: bool = False
    done: bool = False
    failure: str = ''          # why it failed ('' while it runs or when it did what a grasp or release needs)


def judge(command, accepted, status_word, position, stalled, reached):
    """The ``failure`` of ``command`` from its server's answer ('' when it did its job): reaching the target,
    or stopping short of it against something while closing (an apple between the fingers: gripper_action_controller
    reports a stall as aborted unless it allows stalling)."""
    if not accepted:
        return f'the gripper refused the command to {command.target:g}'
    if reached or status_word == 'succeeded':
        return ''
    if stalled and position > command.target:
        return ''                  # closed on something: holding it
    return (f'the gripper ended {status_word} at {position:g} (commanded {command.target:g}'
            f'{", stalled" if stalled else ""})')


@dataclass
class GripperSchedule:
    """The commands of the flights sent to a standard arm controller, by flight key."""

    commands: dict = field(default_factory=dict)

    def plan(self, key, start, moves):
        """Flight ``key``'s trajectory starts at schedule time ``start``: its ``moves`` (from :func:`gripper_moves`)
        become its commands. The commands of every other flight not yet sent at or after ``start`` are dropped
        (the new trajectory replaces the old from its start)."""
        for other, commands in self.commands.items():
            if other != key:
                self.commands[other] = [c for c in commands if c.sent or c.at < start]
        self.commands[key] = [GripperCommand(start + t, target) for t, target in moves]
        return self.commands[key]

    def drop(self, key):
        """Flight ``key`` was canceled or ended: its commands not yet sent never will be."""
        self.commands[key] = [c for c in self.commands.get(key, []) if c.sent]

    def due(self, now):
        """``[(key, command)]`` due at schedule time ``now``, marked sent."""
        out = []
        for key, commands in self.commands.items():
            for c in commands:
                if not c.sent and c.at <= now:
                    c.sent = True
                    out.append((key, c))
        return out

    def next_time(self):
        """The earliest time a command not yet sent is due, or None."""
        times = [c.at for commands in self.commands.values() for c in commands if not c.sent]
        return min(times) if times else None

    def settled(self, key):
        """``(done, failure)`` of flight ``key``: all its sent commands answered, and the first failure ('')."""
        commands = [c for c in self.commands.get(key, []) if c.sent]
        failure = next((c.failure for c in commands if c.failure), '')
        return all(c.done for c in commands), failure

    def forget(self, key):
        self.commands.pop(key, None)
