"""The angular-position servo loop of the paper's Fig. 1, one instance per arm (pure core).

Per joint: a PID on angle with velocity and acceleration feedforward drives a
motor model (inertia, viscous friction, torque and velocity saturation),
integrated with a fixed step (semi-implicit Euler). Everything is vectorised
over joints; the state is two numpy vectors.

Units: rad, rad/s, rad/s^2 for the joints; torques are per unit inertia
scaled by ``inertia`` (N m with inertia in kg m^2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from picking_core.trajectory import quintic

#: s: how far back a servo catching up after a stall takes a command stamped in its future.
#: The middleware has been measured blocking a publishing thread (the servo's, with the GIL)
#: for 0.33 s: such a stall is bridged too, not jumped.
CATCH_UP = 0.5
#: Most servo periods in a command_timeout (a period so short is a mistake: 1e9 is 50 ps at 0.05 s).
MAX_HOLD_STEPS = 1e9


@dataclass
class ServoParams:
    """Servo and motor parameters, one value or one per joint.

    Attributes
    ----------
    bandwidth : float
        Closed-loop natural frequency of the position loop, Hz.
    damping : float
        Damping ratio of the position loop.
    integral : float
        Integral gain relative to the proportional one, 1/s.
    inertia : float
        Joint inertia seen by the motor, kg m^2.
    friction : float
        Viscous friction, N m s/rad.
    max_torque : float
        Torque saturation, N m.
    max_velocity : float or array
        Velocity saturation, rad/s (usually the URDF limits).
    """

    bandwidth: float = 25.0
    damping: float = 1.0
    integral: float = 2.0
    inertia: float = 0.5
    friction: float = 0.8
    max_torque: float = 400.0
    max_velocity: object = np.inf

    def validate(self):
        for name in ('bandwidth', 'damping', 'inertia', 'max_torque'):
            value = np.asarray(getattr(self, name), dtype=float)
            if not np.all(np.isfinite(value)) or np.any(value <= 0):
                raise ValueError(f'servo {name} must be finite and > 0, got {value}')
        for name in ('integral', 'friction'):
            value = np.asarray(getattr(self, name), dtype=float)
            if not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ValueError(f'servo {name} must be finite and >= 0, got {value}')
        if np.any(np.asarray(self.max_velocity, dtype=float) <= 0):
            raise ValueError('servo max_velocity must be > 0')


@dataclass
class Servo:
    """Fixed-step servo simulation of ``n`` joints.

    Parameters
    ----------
    q0 : array_like, shape (n,)
        Initial joint positions, rad.
    dt : float
        Servo period, s (1 ms at the default 1 kHz).
    params : ServoParams
    command_timeout : float
        After this long without a command the reference stops extrapolating
        and holds its position, s: a silent controller never runs the arm away.
    """

    q0: object
    dt: float = 1e-3
    params: ServoParams = field(default_factory=ServoParams)
    command_timeout: float = 0.05

    def __post_init__(self):
        self.params.validate()
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f'servo period must be > 0 s, got {self.dt}')
        if not (np.isfinite(self.command_timeout) and self.command_timeout > 0):
            raise ValueError(f'command_timeout must be > 0 s, got {self.command_timeout}')
        if not self.command_timeout / self.dt < MAX_HOLD_STEPS:
            raise ValueError(f'servo period {self.dt:.3g} s is too short: command_timeout {self.command_timeout} s '
                             f'would be more than {MAX_HOLD_STEPS:.0e} periods')
        self.q = np.array(self.q0, dtype=float).reshape(-1)
        if not np.all(np.isfinite(self.q)):
            raise ValueError('initial positions must be finite')
        n = self.q.size
        p = self.params
        wn = 2.0 * np.pi * np.broadcast_to(np.asarray(p.bandwidth, float), (n,))
        self.inertia = np.broadcast_to(np.asarray(p.inertia, float), (n,)).copy()
        self.kp = self.inertia * wn**2
        self.kd = self.inertia * 2.0 * np.broadcast_to(np.asarray(p.damping, float), (n,)) * wn
        self.ki = self.kp * np.broadcast_to(np.asarray(p.integral, float), (n,))
        self.friction = np.broadcast_to(np.asarray(p.friction, float), (n,)).copy()
        self.max_torque = np.broadcast_to(np.asarray(p.max_torque, float), (n,)).copy()
        self.max_velocity = np.broadcast_to(np.asarray(p.max_velocity, float), (n,)).copy()
        self.qd = np.zeros(n)
        self.integral = np.zeros(n)
        self.torque = np.zeros(n)
        # The reference held between commands: hold the start position.
        self.ref_q, self.ref_qd, self.ref_qdd = self.q.copy(), np.zeros(n), np.zeros(n)
        self._hold_after = max(1, int(round(self.command_timeout / self.dt)))
        self._since_command = self._hold_after          # no command yet: holding
        self._bridge = None                             # catching up: (the quintic to the command, steps, done)
        # Anti-windup: the integral never asks for more than the torque limit.
        self._integral_limit = self.max_torque / np.maximum(self.ki, 1e-12)
        # Contact stops: a joint cannot go below its floor (fingers closing on an apple); -inf: none.
        self.floor = np.full(n, -np.inf)
        self._stops = False

    @property
    def n_joints(self):
        return self.q.size

    @property
    def commanded(self):
        """True while commands come (the reference moves on); False once it holds for lack of them."""
        return self._since_command < self._hold_after

    def command(self, q, qd=None, qdd=None, age=0.0):
        """Set the reference (position, and optionally velocity and acceleration feedforward).

        ``age`` is how long ago the command was sampled, s (its stamp against the
        servo's clock): the reference starts from where the command has moved
        since, so transport delay does not make the arm lag. Ages beyond the
        command timeout are not extrapolated (a stale command is only held). A
        negative age, down to -CATCH_UP s, is a command from the servo's future: a
        servo catching up on steps it missed (its thread was stalled). Its
        reference then goes from where it is (the previous command moved on) to
        the command at the command's own time along the quintic that meets both
        states, as a controller interpolates between trajectory points, instead of
        jumping ahead to it. (Taking the command back in time with its velocity
        and acceleration is off by about jerk x age^3 / 6: 0.13 rad for a 0.2 s
        stall in a brisk move.)
        """
        q = np.asarray(q, dtype=float)
        if q.shape != self.q.shape or not np.isfinite(q.sum()):
            raise ValueError(f'reference must be {self.n_joints} finite positions')
        qd = np.zeros_like(q) if qd is None else np.asarray(qd, dtype=float)
        qdd = np.zeros_like(q) if qdd is None else np.asarray(qdd, dtype=float)
        # One sum is finite only if every term is.
        if qd.shape != q.shape or qdd.shape != q.shape or not np.isfinite(qd.sum() + qdd.sum()):
            raise ValueError(f'velocity and acceleration feedforward must be {self.n_joints} finite values')
        age = float(age)
        if not (np.isfinite(age) and -CATCH_UP <= age < self.command_timeout):
            age = 0.0
        self._bridge = None
        ahead = int(round(-age / self.dt))
        if ahead >= 2:
            self._bridge = (quintic(self.ref_q, q, ahead * self.dt, v0=self.ref_qd, vf=qd, a0=self.ref_qdd, af=qdd),
                            ahead, 0)
        elif age:
            self.ref_q = q + qd * age + 0.5 * qdd * age * age
            self.ref_qd = qd + qdd * age
            self.ref_qdd = qdd.copy()
        else:
            self.ref_q, self.ref_qd, self.ref_qdd = q.copy(), qd.copy(), qdd.copy()
        self._since_command = int(age / self.dt)      # counted from the command's own time

    def stop_at(self, joint, position):
        """Joint ``joint`` cannot move below ``position`` (a contact: the fingers on what they close on) until
        it is set again; ``-inf`` frees it. Pressed against its stop the joint rests there and its integral
        does not wind up."""
        self.floor[joint] = float(position)
        self._stops = bool(np.isfinite(self.floor).any())

    def step(self, steps=1):
        """Advance ``steps`` servo periods; between commands the reference moves on
        with its velocity and acceleration (so a late command does not stall it)."""
        dt = self.dt
        # (Saturation by the ufuncs themselves: np.clip costs several times as much per call on
        # arrays this small, three times a step.)
        lo_i, hi_i = -self._integral_limit, self._integral_limit
        lo_t, hi_t = -self.max_torque, self.max_torque
        lo_v, hi_v = -self.max_velocity, self.max_velocity
        for _ in range(int(steps)):
            e = self.ref_q - self.q
            self.integral += e * dt
            np.minimum(np.maximum(self.integral, lo_i, out=self.integral), hi_i, out=self.integral)
            tau = (self.kp * e + self.kd * (self.ref_qd - self.qd) + self.ki * self.integral
                   + self.inertia * self.ref_qdd + self.friction * self.ref_qd)
            np.minimum(np.maximum(tau, lo_t, out=tau), hi_t, out=tau)
            self.torque = tau
            qdd = (tau - self.friction * self.qd) / self.inertia
            self.qd += qdd * dt
            np.minimum(np.maximum(self.qd, lo_v, out=self.qd), hi_v, out=self.qd)
            self.q += self.qd * dt
            if self._stops:
                pressed = self.q < self.floor
                if pressed.any():
                    self.q[pressed] = self.floor[pressed]
                    self.qd[pressed] = 0.0
                    self.integral[pressed] = 0.0
            self._since_command += 1
            if self._bridge is not None:
                self._bridge_step()
            elif self._since_command < self._hold_after:
                self.ref_q = self.ref_q + self.ref_qd * dt + 0.5 * self.ref_qdd * dt * dt
                self.ref_qd = self.ref_qd + self.ref_qdd * dt
            elif self._since_command == self._hold_after:
                self.ref_qd = np.zeros_like(self.ref_qd)
                self.ref_qdd = np.zeros_like(self.ref_qdd)
        return self.q, self.qd

    def _bridge_step(self):
        """The reference one step further along the catch-up quintic (at its end: the command)."""
        bridge, steps, done = self._bridge
        done += 1
        self.ref_q, self.ref_qd, self.ref_qdd = bridge.state_at(min(done * self.dt, bridge.duration))
        self._bridge = (bridge, steps, done) if done < steps else None
