"""Time profiles of joint (or path) coordinates: the paper's interpolation methods.

>>> from picking_core import trajectory
>>> seg = trajectory.lspb(15.0, 75.0, 3.0, 42.0)     # degrees, s, deg/s^2
>>> q, qd, qdd = seg.sample([0.0, 1.5, 3.0])

Every constructor returns a :class:`PiecewisePolynomial` (or a subclass with
extra attributes) whose ``sample(t)`` gives ``(q, qd, qdd)`` each of shape
``(len(t), n_joints)``.
"""

from .lspb import Lspb, ViaLspb, lspb, min_lspb_accel, via_lspb, via_lspb_timing
from .optimal import time_optimal, time_optimal_stop
from .piecewise import PiecewisePolynomial, concatenate, hold, stack, use_compiled_kernels
from .polynomial import brake, cubic, held_within_limits, hermite_coeffs, quintic
from .via import quintic_via
from .waypoints import STEP, step_pairs, through_waypoints, waypoints

__all__ = [
    'PiecewisePolynomial', 'Lspb', 'ViaLspb',
    'cubic', 'quintic', 'lspb', 'min_lspb_accel', 'via_lspb', 'via_lspb_timing', 'quintic_via',
    'concatenate', 'hold', 'stack', 'hermite_coeffs', 'brake', 'held_within_limits', 'time_optimal',
    'time_optimal_stop', 'use_compiled_kernels', 'waypoints', 'through_waypoints', 'step_pairs', 'STEP',
]
