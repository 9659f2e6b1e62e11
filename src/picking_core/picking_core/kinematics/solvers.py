"""Inverse kinematics solvers: closed form for the shipped geometries, DLS for any chain.

The closed forms cover two arm families. The project's own: a waist joint about
z, a shoulder and an elbow about y (the paper's three joints), and -- for six
joints -- a spherical wrist about z, y, z whose axes meet at the wrist centre.
Universal Robots': three parallel axes (shoulder, elbow, wrist 1) and an offset
wrist (:class:`OffsetWrist6R`). The geometry is read from the URDF, so any arm
of either shape gets the closed form; every other chain gets damped least
squares with joint limits and restarts.

All closed-form work is vectorised over poses and branches. A closed form is
used only after a self-test against forward kinematics when the arm is loaded.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

from ..compiled import load

TWO_PI = 2.0 * np.pi
_Z = np.array([0.0, 0.0, 1.0])
_Y = np.array([0.0, 1.0, 0.0])
_TOL = 1e-9          # geometry detection and FK confirmation
_SINGULAR = 1e-9     # |sin q5| below which the wrist is singular


def pick_solver(arm):
    """The fastest solver that fits the arm's geometry.

    A closed form is accepted only after it reproduces 64 random
    configurations exactly through forward kinematics (a self-test at load
    time), so that no per-call confirmation is needed.
    """
    for cls in (SphericalWrist6R, OffsetWrist6R, Elbow3R):
        solver = cls.fit(arm)
        if solver is not None and solver.self_test():
            return solver
    return NumericSolver(arm)


def _test_poses(arm, n=64):
    """Random configurations within ``arm``'s limits, and their tool poses: a solver's self-test."""
    rng = np.random.default_rng(12345)
    lo = np.where(np.isfinite(arm.lower), arm.lower, -np.pi)
    hi = np.where(np.isfinite(arm.upper), arm.upper, np.pi)
    Q = rng.uniform(lo, hi, (n, arm.dof))
    return Q, arm.joint_frames(Q)[:, -1]


def _confirm(arm, q, T, position_only):
    """Each of ``q`` (N, dof) puts the tool at its pose ``T`` (position only, for an arm that solves no more)."""
    F = arm.joint_frames(q)[:, -1]
    pos_err = np.linalg.norm(F[:, :3, 3] - T[:, :3, 3], axis=1)
    if position_only:
        return pos_err < 1e-7
    rot_err = np.linalg.norm(F[:, :3, :3] - T[:, :3, :3], axis=(1, 2))   # ~ sqrt(2) * angle
    return (pos_err < 1e-7) & (rot_err < 1e-7)


def _is(v, ref):
    return np.allclose(v, ref, atol=_TOL)


def _pure_z_offset(T):
    """The z offset if T is a pure translation along z, else None."""
    if _is(T[:3, :3], np.eye(3)) and abs(T[0, 3]) < _TOL and abs(T[1, 3]) < _TOL:
        return float(T[2, 3])
    return None


def _wrap_into_limits(q, seed, lower, upper, revolute):
    """Shift revolute joints by multiples of 2 pi into the limits, nearest the seed.

    q : (N, B, dof), seed : (N, dof). Returns the shifted q and a (N, B) validity mask.
    """
    s = seed[:, None, :]
    turns = np.rint((s - q) * (1.0 / TWO_PI))                          # the 2 pi image nearest the seed
    if not revolute.all():
        turns *= revolute
    q = q + TWO_PI * turns
    ok = (q >= lower - _TOL) & (q <= upper + _TOL)
    bad = ~ok
    if bad.any():
        # Only the values outside their limits try the next 2 pi images (nearer one first).
        n, b, j = np.nonzero(bad)
        qb = q[n, b, j]
        lo, hi = lower[j] - _TOL, upper[j] + _TOL
        step = np.where(seed[n, j] >= qb, TWO_PI, -TWO_PI) * revolute[j]
        first, second = qb + step, qb - step
        ok_first = (first >= lo) & (first <= hi) & (step != 0)
        ok_second = (second >= lo) & (second <= hi) & (step != 0)
        q[n, b, j] = np.where(ok_first, first, np.where(ok_second, second, qb))
        ok[n, b, j] = ok_first | ok_second
    return q, ok.all(axis=-1)


class _ClosedForm:
    """Shared shape of the closed-form solvers."""

    name = ''
    position_only = False
    kernel = 'fast_ik'      # the module of the compiled version

    def __init__(self, arm, base, d_shoulder, l2, l3):
        self.arm = arm
        self.shoulder = base + np.array([0.0, 0.0, d_shoulder])
        self.l2, self.l3 = l2, l3
        self.reach = (abs(l2 - l3), l2 + l3)
        self.revolute = np.array([t != 'prismatic' for t in arm.joint_types], dtype=float)

    # Position part: waist, shoulder and elbow for wrist-centre targets W (N, 3),
    # four branches (front/back x elbow up/down). Returns (N, 4, 3) and reach mask (N,).
    def _arm_branches(self, W, seed):
        p = W - self.shoulder
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        rho = np.hypot(x, y)
        on_axis = rho < _TOL
        q1a = np.where(on_axis, seed[:, 0], np.arctan2(y, x))
        q1 = np.stack([q1a, q1a, q1a + np.pi, q1a + np.pi], axis=1)
        r = np.stack([rho, rho, -rho, -rho], axis=1)
        l2, l3 = self.l2, self.l3
        D = (rho**2 + z**2 - l2**2 - l3**2) / (2.0 * l2 * l3)
        reach_ok = np.abs(D) <= 1.0 + 1e-12
        q3p = np.arccos(np.clip(D, -1.0, 1.0))
        q3 = np.stack([q3p, -q3p, q3p, -q3p], axis=1)
        q2 = np.arctan2(r, z[:, None]) - np.arctan2(l3 * np.sin(q3), l2 + l3 * np.cos(q3))
        return np.stack([q1, q2, q3], axis=2), reach_ok

    def _reach_reason(self, W):
        d = float(np.linalg.norm(W - self.shoulder))
        lo, hi = self.reach
        what = 'wrist centre' if not self.position_only else 'tool point'
        if d > hi:
            return f'out of reach: the {what} would be {d:.3f} m from the shoulder, the arm reaches {hi:.3f} m'
        if d < lo:
            return f'out of reach: the {what} would be {d:.3f} m from the shoulder, closer than {lo:.3f} m'
        return ''

    def quick_reject(self, T):
        return self.reach_reasons(T[None])[0]

    def _test_poses(self):
        return _test_poses(self.arm)

    def self_test(self):
        """IK of FK of random configurations within the limits gives poses back exactly."""
        Q, T = self._test_poses()
        q, ok, _ = self.solve(T, Q)
        return bool(ok.all() and self._confirm(q, T).all())

    @functools.cached_property
    def compiled(self):
        """The compiled solver bound to this arm (:class:`.fast_ik.Bound`: ``one`` pose, ``many``).

        Loaded on first use, and used only if it gives the vectorised path's solutions
        for the self-test poses (seeded off their configurations). None without numba,
        or (with a warning) if numba cannot compile or cache it here.
        """
        fast_ik = load(f'{__package__}.{self.kernel}', 'the compiled IK', 'IK runs the vectorised closed form')
        if fast_ik is None:
            return None
        bound = fast_ik.bind(self)
        Q, T = self._test_poses()
        T = np.ascontiguousarray(T)
        seeds = np.roll(Q, 1, axis=0)
        expected, ok, _ = self.solve(T, seeds)
        q, status = np.empty_like(Q), np.empty(len(T), dtype=np.int64)
        bound.many(T, seeds, q, status)
        one = np.empty(self.arm.dof)
        for i in range(len(T)):
            agree = [(s == fast_ik.OK) == ok[i] and (not ok[i] or np.allclose(x, expected[i], atol=1e-9))
                     for s, x in ((bound.one(T[i], seeds[i], one), one), (status[i], q[i]))]
            if not all(agree):
                warnings.warn('the compiled IK disagrees with the vectorised closed form on its self-test: '
                              'IK runs the vectorised closed form', RuntimeWarning, stacklevel=2)
                return None
        return bound

    def solve(self, T, seed):
        cand, reach_ok = self.candidates(T, seed)                     # (N, B, dof)
        cand, in_limits = _wrap_into_limits(cand, seed, self.arm.lower, self.arm.upper, self.revolute)
        valid = in_limits & reach_ok[:, None]
        d = cand - seed[:, None, :]
        dist = np.where(valid, np.einsum('nbj,nbj->nb', d, d), np.inf)
        rows = np.arange(len(T))
        best = np.argmin(dist, axis=1)
        q = cand[rows, best]
        ok = valid[rows, best] & np.isfinite(q).all(axis=1)
        q[~ok] = np.nan
        reasons = [''] * len(T)
        failed = np.flatnonzero(~ok)
        why = self.reach_reasons(T[failed]) if failed.size else []
        for i, reason in zip(failed, why):
            reasons[i] = reason or 'beyond joint limits: every IK solution puts a joint outside its limits'
        return q, ok, reasons

    def reach_reasons(self, T):
        """Why each pose is out of reach, '' where it is within reach."""
        return [self._reach_reason(w) for w in self._targets(T)]

    def all_solutions(self, T):
        seed = np.broadcast_to(self.arm._seed(None), (len(T), self.arm.dof))
        cand, reach_ok = self.candidates(T, seed)
        return [c[np.isfinite(c).all(axis=1)] if r else c[:0] for c, r in zip(cand, reach_ok)]

    def _confirm(self, q, T):
        return _confirm(self.arm, q, T, self.position_only)


class Elbow3R(_ClosedForm):
    """The paper's three joints (waist z, shoulder y, elbow y): position-only IK, 4 solutions."""

    name = 'elbow_3r'
    position_only = True

    @classmethod
    def fit(cls, arm):
        if arm.dof != 3 or any(t == 'prismatic' for t in arm.joint_types):
            return None
        ax, o = arm._axes, arm._origins
        if not (_is(ax[0], _Z) and _is(ax[1], _Y) and _is(ax[2], _Y) and _is(o[0][:3, :3], np.eye(3))):
            return None
        d, l2, l3 = _pure_z_offset(o[1]), _pure_z_offset(o[2]), _pure_z_offset(arm._tool)
        if d is None or l2 is None or l3 is None or l2 <= 0 or l3 <= 0:
            return None
        return cls(arm, o[0][:3, 3], d, l2, l3)

    def _targets(self, T):
        return T[:, :3, 3]

    def candidates(self, T, seed):
        return self._arm_branches(self._targets(T), seed)


class SphericalWrist6R(_ClosedForm):
    """Waist z, shoulder y, elbow y, wrist z-y-z meeting at one point: up to 8 solutions."""

    name = 'spherical_wrist'

    @classmethod
    def fit(cls, arm):
        if arm.dof != 6 or any(t == 'prismatic' for t in arm.joint_types):
            return None
        ax, o = arm._axes, arm._origins
        if not all(_is(a, ref) for a, ref in zip(ax, (_Z, _Y, _Y, _Z, _Y, _Z))):
            return None
        if not _is(o[0][:3, :3], np.eye(3)):
            return None
        d, l2, l3 = _pure_z_offset(o[1]), _pure_z_offset(o[2]), _pure_z_offset(o[3])
        if None in (d, l2, l3) or l2 <= 0 or l3 <= 0:
            return None
        if not (_is(o[4], np.eye(4)) and _is(o[5], np.eye(4))):
            return None
        solver = cls(arm, o[0][:3, 3], d, l2, l3)
        solver.tool_inv = np.linalg.inv(arm._tool)
        return solver

    def _targets(self, T):
        return (T @ self.tool_inv)[:, :3, 3]

    def candidates(self, T, seed):
        flange = T @ self.tool_inv
        arm_q, reach_ok = self._arm_branches(flange[:, :3, 3], seed)   # (N, 4, 3)
        q1, q23 = arm_q[..., 0], arm_q[..., 1] + arm_q[..., 2]
        c1, s1, c23, s23 = np.cos(q1), np.sin(q1), np.cos(q23), np.sin(q23)
        # Only the five entries of R36 = (Rz(q1) Ry(q2 + q3))^T R06 that ZYZ needs (the scalar
        # path's formulas, broadcast over poses and branches).
        F = flange[:, None, :3, :3]
        a0, a1, a2 = c1 * c23, s1 * c23, -s23
        e0, e1, e2 = c1 * s23, s1 * s23, c23
        r02 = a0 * F[..., 0, 2] + a1 * F[..., 1, 2] + a2 * F[..., 2, 2]
        r12 = -s1 * F[..., 0, 2] + c1 * F[..., 1, 2]
        r22 = e0 * F[..., 0, 2] + e1 * F[..., 1, 2] + e2 * F[..., 2, 2]
        r20 = e0 * F[..., 0, 0] + e1 * F[..., 1, 0] + e2 * F[..., 2, 0]
        r21 = e0 * F[..., 0, 1] + e1 * F[..., 1, 1] + e2 * F[..., 2, 1]
        s5 = np.hypot(r02, r12)
        q5 = np.arctan2(s5, r22)
        q4 = np.arctan2(r12, r02)
        q6 = np.arctan2(r21, -r20)
        singular = s5 < _SINGULAR
        if singular.any():
            # Only q4 + q6 (or q4 - q6 when q5 = pi) is defined: keep q4 at the seed.
            r00 = a0 * F[..., 0, 0] + a1 * F[..., 1, 0] + a2 * F[..., 2, 0]
            r10 = -s1 * F[..., 0, 0] + c1 * F[..., 1, 0]
            r01 = a0 * F[..., 0, 1] + a1 * F[..., 1, 1] + a2 * F[..., 2, 1]
            r11 = -s1 * F[..., 0, 1] + c1 * F[..., 1, 1]
            q4s = np.broadcast_to(seed[:, None, 3], q4.shape)
            q6s = np.where(r22 > 0, np.arctan2(r10, r00) - q4s, q4s - np.arctan2(-r01, r11))
            q4 = np.where(singular, q4s, q4)
            q6 = np.where(singular, q6s, q6)
        out = np.empty(q1.shape[:1] + (8, 6))
        out[:, :4, :3] = arm_q
        out[:, 4:, :3] = arm_q
        out[:, :4, 3], out[:, :4, 4], out[:, :4, 5] = q4, q5, q6
        out[:, 4:, 3], out[:, 4:, 4], out[:, 4:, 5] = q4 + np.pi, -q5, q6 + np.pi
        return out, reach_ok                                           # (N, 8, 6)


def _line_meet(p, u, r, w):
    """The point where the line through ``p`` along ``u`` meets the line through ``r`` along ``w``, or None."""
    n = np.cross(u, w)
    nn = n @ n
    if nn < _TOL:
        return None
    d = r - p
    if abs(d @ n) > _TOL * np.sqrt(nn):                                # skew lines
        return None
    return p + u * (np.cross(d, w) @ n) / nn


def _unit(v):
    return v / np.linalg.norm(v)


def _dh(theta, d, a, ca, sa):
    """Denavit-Hartenberg transforms Rz(theta) Tz(d) Tx(a) Rx(alpha), theta (...,), shape (..., 4, 4)."""
    c, s = np.cos(theta), np.sin(theta)
    A = np.zeros(theta.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = c, -s * ca, s * sa, a * c
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = s, c * ca, -c * sa, a * s
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, d
    A[..., 3, 3] = 1.0
    return A


def _rigid_inv(A):
    """Inverse of rigid transforms (..., 4, 4)."""
    out = np.zeros_like(A)
    Rt = np.swapaxes(A[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum('...ij,...j->...i', Rt, A[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


#: (cos alpha, sin alpha) of the six joints' Denavit-Hartenberg twists in Universal Robots' convention.
UR_TWIST = ((0.0, 1.0), (1.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 0.0))


class OffsetWrist6R(_ClosedForm):
    """Universal Robots' geometry: up to 8 solutions.

    The waist's axis meets the shoulder's; shoulder, elbow and wrist 1 are
    parallel; wrist 1 meets wrist 2 and wrist 2 meets wrist 3, at right angles
    (an offset wrist, no wrist centre). The URDF is read into Denavit-Hartenberg
    form (``d4, d5, d6, a2, a3`` and the twists of :data:`UR_TWIST`) between a
    fixed base and tool transform, with each joint's zero offset, and solved by
    the published analytic solution (K. Hawkins, "Analytic Inverse Kinematics for
    the Universal Robots UR-5/UR-10 Arms", 2013): two waist angles, two wrist 2
    angles, two elbow angles.
    """

    name = 'offset_wrist'
    kernel = 'fast_ik_ur'

    def __init__(self, arm, base, tool, offsets, d4, d5, d6, a2, a3):
        self.arm = arm
        self.base_inv, self.tool_inv = _rigid_inv(base), _rigid_inv(tool)
        self.offsets = np.asarray(offsets, dtype=float)
        self.d4, self.d5, self.d6, self.a2, self.a3 = d4, d5, d6, a2, a3
        self.reach = (abs(a2 - a3), a2 + a3)
        self.revolute = np.ones(6)

    @classmethod
    def fit(cls, arm):
        if arm.dof != 6 or any(t == 'prismatic' for t in arm.joint_types):
            return None
        frames = arm.joint_frames(np.zeros((1, 6)))[0]
        w = [_unit(frames[i, :3, :3] @ arm._axes[i]) for i in range(6)]
        r = [frames[i, :3, 3] for i in range(6)]
        if not (abs(w[0] @ w[1]) < _TOL and _is(w[1], w[2]) and _is(w[2], w[3])
                and abs(w[3] @ w[4]) < _TOL and abs(w[4] @ w[5]) < _TOL):
            return None
        shoulder = _line_meet(r[0], w[0], r[1], w[1])
        wrist_1 = _line_meet(r[3], w[3], r[4], w[4])
        wrist_2 = _line_meet(r[4], w[4], r[5], w[5])
        if shoulder is None or wrist_1 is None or wrist_2 is None:
            return None
        # Denavit-Hartenberg frames 0..6 at the zero configuration; frame i-1's z is joint i's axis.
        z = [w[0], w[1], w[2], w[3], w[4], w[5], w[5]]
        x = [None] * 7
        x[1] = x[0] = _unit(np.cross(z[0], z[1]))
        origin = [shoulder, shoulder, None, None, wrist_1, wrist_2, None]
        lengths = []
        for i in (2, 3):            # across the parallel axes, from the last origin to the next axis
            v = r[i] - origin[i - 1]
            v = v - (v @ z[i - 1]) * z[i - 1]
            lengths.append(float(np.linalg.norm(v)))
            if lengths[-1] < 1e-6:
                return None
            x[i], origin[i] = v / lengths[-1], origin[i - 1] + v
        x[4] = _unit(np.cross(z[3], z[4]))
        x[6] = x[5] = _unit(np.cross(z[5], z[4]))
        d4 = float((wrist_1 - origin[3]) @ z[3])
        d5 = float((wrist_2 - wrist_1) @ z[4])
        d6 = float((frames[-1, :3, 3] - wrist_2) @ z[5])
        if abs(d6) < 0.01:
            d6 = 0.1           # any flange distance along wrist 3 will do; the tool transform takes the rest
        origin[6] = wrist_2 + d6 * z[6]
        offsets = [float(np.arctan2(np.cross(x[i], x[i + 1]) @ z[i], x[i] @ x[i + 1])) for i in range(6)]

        def frame(i):
            F = np.eye(4)
            F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = x[i], np.cross(z[i], x[i]), z[i], origin[i]
            return F

        return cls(arm, frame(0), _rigid_inv(frame(6)) @ frames[-1], offsets, d4, d5, d6, *lengths)

    def _chain(self, theta, i):
        ca, sa = UR_TWIST[i]
        d = (0.0, 0.0, 0.0, self.d4, self.d5, self.d6)[i]
        a = (0.0, self.a2, self.a3, 0.0, 0.0, 0.0)[i]
        return _dh(theta, d, a, ca, sa)

    def _flange(self, T):
        """The poses as Denavit-Hartenberg frame 6 in frame 0."""
        return self.base_inv @ T @ self.tool_inv

    def candidates(self, T, seed):
        n = len(T)
        F = self._flange(T)
        R, p = F[:, :3, :3], F[:, :3, 3]
        d4, d6, a2, a3 = self.d4, self.d6, self.a2, self.a3
        p5 = p - d6 * R[:, :, 2]
        rho = np.hypot(p5[:, 0], p5[:, 1])
        psi = np.arctan2(p5[:, 1], p5[:, 0])
        with np.errstate(invalid='ignore', divide='ignore'):
            delta = np.arcsin(d4 / rho)                                 # NaN inside the shoulder offset
            t1 = np.stack([psi + delta, psi + np.pi - delta], axis=1)           # (N, 2)
            s1, c1 = np.sin(t1), np.cos(t1)
            # Wrist 2: its cosine from the position, its sine's size from the orientation (well
            # conditioned near the singular wrist, where an arc cosine is not).
            c5 = (p[:, None, 0] * s1 - p[:, None, 1] * c1 - d4) / d6
            u = R[:, None, 0, 0] * s1 - R[:, None, 1, 0] * c1
            v = R[:, None, 0, 1] * s1 - R[:, None, 1, 1] * c1
            s5 = np.where(np.abs(c5) <= 1.0 + 1e-12, np.hypot(u, v), np.nan)
            t1 = np.repeat(t1, 2, axis=1)                                      # (N, 4): waist x wrist 2
            sign = np.array([1.0, -1.0, 1.0, -1.0])
            c5, s5, u, v = (np.repeat(a, 2, axis=1) for a in (c5, s5, u, v))
            t5 = np.arctan2(sign * s5, c5)
            singular = s5 < _SINGULAR
            t6 = np.where(singular, seed[:, None, 5] + self.offsets[5], np.arctan2(-sign * v, sign * u))
            # Frame 4 in frame 1: the planar shoulder-elbow-wrist 1 problem.
            T14 = (_rigid_inv(self._chain(t1, 0)) @ F[:, None] @ _rigid_inv(self._chain(t6, 5))
                   @ _rigid_inv(self._chain(t5, 4)))
            x, y = T14[..., 0, 3], T14[..., 1, 3]
            D = (x * x + y * y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
            t3p = np.arccos(np.where(np.abs(D) <= 1.0 + 1e-12, np.clip(D, -1.0, 1.0), np.nan))
            t3 = np.concatenate([t3p, -t3p], axis=1)                            # (N, 8)
            x, y = np.tile(x, 2), np.tile(y, 2)
            t2 = np.arctan2(y, x) - np.arctan2(a3 * np.sin(t3), a2 + a3 * np.cos(t3))
            phi = np.tile(np.arctan2(T14[..., 1, 0], T14[..., 0, 0]), 2)
            theta = np.stack([np.tile(t1, 2), t2, t3, phi - t2 - t3, np.tile(t5, 2), np.tile(t6, 2)], axis=2)
        q = theta - self.offsets
        q[~np.isfinite(q).all(axis=2)] = np.nan
        return q, np.isfinite(q).all(axis=2).any(axis=1).reshape(n)

    def reach_reasons(self, T):
        F = self._flange(T)
        reasons = []
        for f, (cand, ok) in zip(F, zip(*self.candidates(T, np.zeros((len(T), 6))))):
            p5 = f[:3, 3] - self.d6 * f[:3, 2]
            rho = float(np.hypot(p5[0], p5[1]))
            if ok:
                reasons.append('')
            elif rho < abs(self.d4):
                reasons.append(f'out of reach: wrist 2 would be {rho:.3f} m from the waist axis, closer than the '
                               f'shoulder offset {abs(self.d4):.3f} m')
            else:
                reasons.append(f'out of reach: no shoulder and elbow angles put the wrist there (upper arm '
                               f'{self.a2:.3f} m, forearm {self.a3:.3f} m)')
        return reasons


class NumericSolver:
    """Levenberg-Marquardt (damped least squares) with joint limits and restarts, for any serial chain.

    Compiled (:mod:`.fast_ik_numeric`) where numba is, after a self-test; the
    same method in numpy otherwise. Arms with fewer than six joints solve the
    tool position only. A pose is called out of reach only when it is farther
    from the first joint than the chain is long; any other failure is "no
    solution found".
    """

    name = 'numeric'

    def __init__(self, arm, restarts=100, iterations=30):
        self.arm = arm
        self.position_only = arm.dof < 6
        self.restarts, self.iterations = restarts, iterations
        origins = arm.joint_frames(np.zeros((1, arm.dof)))[0]
        hops = np.linalg.norm(np.diff(origins[:, :3, 3], axis=0), axis=1)
        prismatic_travel = np.where(arm._prismatic, np.abs(np.nan_to_num(arm.upper, posinf=0.0)), 0.0)
        self.base_point = origins[0, :3, 3]
        self.reach = (0.0, float(hops.sum() + prismatic_travel.sum()))

    @functools.cached_property
    def compiled(self):
        """The compiled solver bound to this arm, or None (without numba, or if it fails its
        self-test: 64 random configurations' poses solved, each confirmed by forward kinematics)."""
        kernel = load(f'{__package__}.fast_ik_numeric', 'the compiled numeric IK', 'IK runs in numpy')
        if kernel is None:
            return None
        bound = kernel.bind(self)
        Q, T = _test_poses(self.arm)
        q, status = np.empty_like(Q), np.empty(len(Q), dtype=np.int64)
        bound.many(np.ascontiguousarray(T), np.ascontiguousarray(np.roll(Q, 1, axis=0)), q, status)
        ok = status == kernel.OK
        if ok.mean() < 0.9 or not _confirm(self.arm, q[ok], T[ok], self.position_only).all():
            warnings.warn('the compiled numeric IK failed its self-test: IK runs in numpy', RuntimeWarning,
                          stacklevel=2)
            return None
        return bound

    def quick_reject(self, T):
        d = float(np.linalg.norm(T[:3, 3] - self.base_point))
        if d > self.reach[1] + 1e-9:
            return (f'out of reach: the tool would be {d:.3f} m from the first joint, '
                    f'the chain is {self.reach[1]:.3f} m long')
        return ''

    def all_solutions(self, T):
        q, ok, _ = self.solve(T, np.broadcast_to(self.arm._seed(None), (len(T), self.arm.dof)))
        return [q[i:i + 1] if ok[i] else q[i:i] for i in range(len(T))]

    def _no_solution(self):
        return (f'no solution found: the numeric IK converged from none of {self.restarts + 1} starts within '
                f'the joint limits (the pose is within the chain\'s length: it may be reachable)')

    def solve(self, T, seed):
        n = len(T)
        reasons = [self.quick_reject(t) for t in T]
        compiled = self.compiled
        if compiled is not None:
            q, status = np.empty((n, self.arm.dof)), np.empty(n, dtype=np.int64)
            compiled.many(np.array(T, dtype=float), np.array(seed, dtype=float), q, status)   # writable copies
            ok = status == 0
            q[~ok] = np.nan
            return q, ok, [r if r or k else self._no_solution() for r, k in zip(reasons, ok)]
        q = np.full((n, self.arm.dof), np.nan)
        ok = np.zeros(n, bool)
        for i in range(n):
            if not reasons[i]:
                sol = self._solve_one(T[i], seed[i])
                if sol is None:
                    reasons[i] = self._no_solution()
                else:
                    q[i], ok[i] = sol, True
        return q, ok, reasons

    def _error(self, q, T):
        F = self.arm.joint_frames(q[None])[0, -1]
        e_pos = T[:3, 3] - F[:3, 3]
        if self.position_only:
            return e_pos
        from scipy.spatial.transform import Rotation
        e_rot = Rotation.from_matrix(T[:3, :3] @ F[:3, :3].T).as_rotvec()
        return np.concatenate([e_pos, e_rot])

    def _solve_one(self, T, seed):
        """The compiled kernel's method in numpy (its fallback): a solution, or None."""
        arm = self.arm
        lo = np.where(np.isfinite(arm.lower), arm.lower, -np.pi)
        hi = np.where(np.isfinite(arm.upper), arm.upper, np.pi)
        rng = np.random.default_rng(0)
        starts = [seed] + [rng.uniform(lo, hi) for _ in range(self.restarts)]
        rows = slice(0, 3) if self.position_only else slice(0, 6)
        for q in starts:
            q = np.clip(q, arm.lower, arm.upper)
            e = self._error(q, T)
            err, lam = np.linalg.norm(e), 1e-3
            for _ in range(self.iterations):
                if err < 1e-10:
                    return q
                J = arm.jacobian(q)[rows]
                dq = J.T @ np.linalg.solve(J @ J.T + lam * np.eye(J.shape[0]), e)
                dq *= min(1.0, 0.5 / max(np.abs(dq).max(), 1e-300))
                trial = np.clip(q + dq, arm.lower, arm.upper)
                e_trial = self._error(trial, T)
                if np.linalg.norm(e_trial) < err:
                    q, e, err, lam = trial, e_trial, np.linalg.norm(e_trial), max(lam * 0.3, 1e-12)
                else:
                    lam *= 10.0
                    if lam > 1e4:
                        break
            if err < 1e-10:
                return q
        return None
