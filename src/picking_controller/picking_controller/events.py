"""The controller's values and events: its modes, tolerances, the event it reports, and the refusal of a trajectory
that came too late (pure core)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field


class Mode(str, enum.Enum):
    """What the controller is doing: waiting for its first feedback, holding a position, moving
    along a trajectory, or holding after a fault (a tolerance violated) until a new trajectory."""

    WAITING = 'waiting'
    HOLDING = 'holding'
    MOVING = 'moving'
    FAULT = 'fault'


class LateTrajectory(ValueError):
    """A trajectory whose start (its stamp) had passed when it came: its sender may plan it again from a later
    start; a trajectory refused otherwise is at fault itself."""

@dataclass(frozen=True)
class Tolerances:
    """Tracking tolerances (rad, s), one value for every joint or one per joint."""

    path: float = 0.1                    # largest |measured - reference| while moving
    goal: float = 0.005                  # at the end
    goal_time: float = 2.0               # s after the end to get within ``goal``
    stopped_velocity: float = 0.02       # rad/s, "at rest" at the goal
    state_timeout: float = 0.5           # s without joint_states before "feedback lost"


@dataclass
class Event:
    """Something the node reports on ``controller_status``."""

    level: str                           # 'OK', 'WARN' or 'ERROR' (picking_common's Level names)
    message: str
    values: dict = field(default_factory=dict)
    goal: object = None                  # the goal this event ends (with ``outcome``), if any
    outcome: object = None               # its goals.Outcome
