"""The arm model: a serial chain read from a URDF, its forward kinematics and limits."""

from __future__ import annotations

import functools
import math
import warnings
from pathlib import Path

import numpy as np

from ..compiled import load
from .errors import Unreachable
from .urdf import chain, default_tip, parse_urdf


def _axis_rotations(axis, q):
    """Rotation matrices about a unit ``axis`` by angles ``q`` (N,), shape (N, 3, 3)."""
    x, y, z = axis
    c, s = np.cos(q), np.sin(q)
    C = 1.0 - c
    R = np.empty(q.shape + (3, 3))
    R[..., 0, 0] = c + x * x * C
    R[..., 0, 1] = x * y * C - z * s
    R[..., 0, 2] = x * z * C + y * s
    R[..., 1, 0] = y * x * C + z * s
    R[..., 1, 1] = c + y * y * C
    R[..., 1, 2] = y * z * C - x * s
    R[..., 2, 0] = z * x * C - y * s
    R[..., 2, 1] = z * y * C + x * s
    R[..., 2, 2] = c + z * z * C
    return R


class ArmModel:
    """A serial arm from ``base_link`` to the tool.

    Attributes
    ----------
    joint_names : tuple of str
        Movable joints, base first.
    lower, upper : ndarray, shape (dof,)
        Position limits, rad or m (+-inf for continuous joints).
    max_velocity, max_acceleration, max_jerk : ndarray, shape (dof,)
        Limits; inf where none is given.
    base_frame, tool_frame : str
    solver : str
        ``'spherical_wrist'`` (closed-form 6R, up to 8 solutions),
        ``'elbow_3r'`` (closed-form position IK, up to 4), or ``'numeric'``.
    """

    def __init__(self, urdf_text: str, base: str = 'base_link', tip: str | None = None,
                 joint_limits: dict | None = None):
        self.name, links, joints = parse_urdf(urdf_text)
        if base not in links:
            raise ValueError(f'base frame {base!r} is not a link of the URDF')
        if tip is None:
            tip = 'tool0' if 'tool0' in links else default_tip(links, joints, base)
        if tip not in links:
            raise ValueError(f'tool frame {tip!r} is not a link of the URDF')
        self.base_frame, self.tool_frame = base, tip
        self.urdf, self.urdf_dir = urdf_text, None
        origins, axes, types, movable = [], [], [], []
        pending = np.eye(4)   # fixed joints folded into the next movable joint's origin
        for joint in chain(joints, base, tip):
            pending = pending @ joint.origin
            if joint.type == 'fixed':
                continue
            origins.append(pending)
            axes.append(joint.axis)
            types.append(joint.type)
            movable.append(joint)
            pending = np.eye(4)
        if not movable:
            raise ValueError(f'no movable joint between {base!r} and {tip!r}')
        self._origins = np.array(origins)
        self._axes = np.array(axes)
        self._prismatic = np.array([t == 'prismatic' for t in types])
        self._tool = pending
        self.joint_types = tuple(types)
        self.joint_names = tuple(j.name for j in movable)
        self.lower = np.array([j.lower for j in movable])
        self.upper = np.array([j.upper for j in movable])
        self.max_velocity = np.array([j.velocity for j in movable])
        self.max_acceleration = np.full(self.dof, np.inf)
        self.max_jerk = np.full(self.dof, np.inf)
        # Movable joints off the base-to-tool chain (a gripper): moved, not solved for.
        in_chain = set(self.joint_names)
        extra = [j for j in joints.values() if j.type != 'fixed' and j.name not in in_chain]
        self.extra_joint_names = tuple(j.name for j in extra)
        #: The gripper's joint (its opening): the one movable joint off the chain, or among several the one named
        #: gripper_joint; None when there is none to tell.
        self.gripper_joint = (extra[0].name if len(extra) == 1 else
                              'gripper_joint' if 'gripper_joint' in self.extra_joint_names else None)
        self._extra = {
            'lower': np.array([j.lower for j in extra]), 'upper': np.array([j.upper for j in extra]),
            'velocity': np.array([j.velocity for j in extra]), 'acceleration': np.full(len(extra), np.inf)}
        if joint_limits:
            self._apply_joint_limits(joint_limits)
        for a in (self.lower, self.upper, self.max_velocity, self.max_acceleration, self.max_jerk):
            a.flags.writeable = False
        from .solvers import pick_solver
        self._solver = pick_solver(self)
        self.solver = self._solver.name

    # -- construction ------------------------------------------------------
    @classmethod
    def from_urdf(cls, path, base='base_link', tip=None, joint_limits=None):
        """Load a URDF file; ``joint_limits`` is a MoveIt joint_limits.yaml path or dict.

        If ``joint_limits`` is None and ``<urdf stem>_joint_limits.yaml`` lies beside the
        URDF, it is read.
        """
        path = Path(path)
        if joint_limits is None:
            beside = path.with_name(path.stem + '_joint_limits.yaml')
            joint_limits = beside if beside.exists() else None
        if isinstance(joint_limits, (str, Path)):
            joint_limits = load_joint_limits(joint_limits)
        arm = cls(path.read_text(), base, tip, joint_limits)
        arm.urdf_dir = path.resolve().parent         # where its meshes' relative paths start
        return arm

    @classmethod
    def from_urdf_string(cls, text, base='base_link', tip=None, joint_limits=None):
        """Build from URDF text, as published on ``robot_description``."""
        return cls(text, base, tip, joint_limits)

    @property
    def all_joint_names(self):
        """The chain's joints, then the extra ones (gripper): what the simulator and controller move."""
        return self.joint_names + self.extra_joint_names

    @property
    def all_limits(self):
        """``(lower, upper, max_velocity, max_acceleration)`` over :attr:`all_joint_names`."""
        e = self._extra
        return (np.concatenate([self.lower, e['lower']]), np.concatenate([self.upper, e['upper']]),
                np.concatenate([self.max_velocity, e['velocity']]),
                np.concatenate([self.max_acceleration, e['acceleration']]))

    def _apply_joint_limits(self, limits):
        table = limits.get('joint_limits', limits)
        for i, name in enumerate(self.extra_joint_names):
            entry = table.get(name) or {}
            if entry.get('has_acceleration_limits') and 'max_acceleration' in entry:
                self._extra['acceleration'][i] = float(entry['max_acceleration'])
        table = {k: v for k, v in table.items() if k not in self.extra_joint_names}
        unknown = set(table) - set(self.joint_names)
        if unknown:
            raise ValueError(f'joint limits name joints that are not in the arm: {sorted(unknown)}')
        for i, name in enumerate(self.joint_names):
            entry = table.get(name) or {}
            for key, target in (('velocity', self.max_velocity), ('acceleration', self.max_acceleration),
                                ('jerk', self.max_jerk)):
                if entry.get(f'has_{key}_limits') and f'max_{key}' in entry:
                    value = float(entry[f'max_{key}'])
                    if not value > 0 or not np.isfinite(value):
                        raise ValueError(f'{name}: max_{key} must be a finite number > 0, got {value}')
                    target[i] = value
            if entry.get('has_position_limits'):
                self.lower[i] = float(entry.get('min_position', self.lower[i]))
                self.upper[i] = float(entry.get('max_position', self.upper[i]))

    def missing_limits(self):
        """'' when every joint of the chain has finite velocity, acceleration and jerk limits (and the extra
        joints velocity and acceleration), else which are missing, in words."""
        _, _, v, a = self.all_limits
        names = self.all_joint_names
        missing = [f'{kind} limit for {", ".join(n for n, x in zip(names, values) if not np.isfinite(x))}'
                   for kind, values in (('velocity', v), ('acceleration', a), ('jerk', self.max_jerk))
                   if not np.isfinite(values).all()]
        return f'{self.name} has no {"; no ".join(missing)}' if missing else ''

    def __repr__(self) -> str:
        return (f'ArmModel({self.name!r}, dof={self.dof}, {self.base_frame} -> {self.tool_frame}, '
                f'solver={self.solver!r})')

    @property
    def dof(self) -> int:
        return len(self._axes)

    # -- checks ------------------------------------------------------------
    def check_joints(self, q, what='q'):
        """``q`` as a finite (N, dof) or (dof,) array, else ValueError."""
        arr = np.asarray(q, dtype=float)
        if arr.shape[-1:] != (self.dof,) or arr.ndim > 2:
            raise ValueError(f'{what} must have {self.dof} joint values (shape (dof,) or (N, dof)), '
                             f'got shape {arr.shape}')
        if not np.isfinite(arr).all():
            raise ValueError(f'{what} must be finite')
        return arr

    def within_limits(self, q, tol=1e-9):
        """Boolean (N,) or scalar: every joint of ``q`` inside its position limits."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)

    # -- forward kinematics ------------------------------------------------
    def joint_frames(self, q):
        """Frames of every movable joint (after its motion) and of the tool.

        Parameters
        ----------
        q : array_like, shape (N, dof)

        Returns
        -------
        ndarray, shape (N, dof + 1, 4, 4)
            ``[:, i]`` is joint i's frame in the base frame; ``[:, -1]`` the tool.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        compiled = self._fk_compiled
        if compiled is None or q.ndim != 2 or q.shape[1] != self.dof:
            return self._joint_frames_numpy(q)
        out = np.empty((q.shape[0], self.dof + 1, 4, 4))
        compiled.frames(_plain_floats(q), out)
        return out

    def _joint_frames_numpy(self, q):
        """:meth:`joint_frames` vectorised over N with numpy (without numba, and its reference)."""
        n = q.shape[0]
        out = np.empty((n, self.dof + 1, 4, 4))
        T = np.broadcast_to(np.eye(4), (n, 4, 4))
        motion = np.zeros((n, 4, 4))
        motion[:, 3, 3] = 1.0
        for i in range(self.dof):
            if self._prismatic[i]:
                motion[:, :3, :3] = np.eye(3)
                motion[:, :3, 3] = q[:, i, None] * self._axes[i]
            else:
                motion[:, :3, :3] = _axis_rotations(self._axes[i], q[:, i])
                motion[:, :3, 3] = 0.0
            T = (T @ self._origins[i]) @ motion
            out[:, i] = T
        out[:, -1] = T @ self._tool
        return out

    def fk(self, q):
        """Tool pose in the base frame.

        Parameters
        ----------
        q : array_like, shape (dof,) or (N, dof)
            Joint positions, rad (m for prismatic joints).

        Returns
        -------
        ndarray, shape (4, 4) or (N, 4, 4)
            Homogeneous transforms; batched without a Python loop over N.
        """
        q = self.check_joints(q)
        batch = np.atleast_2d(q)
        compiled = self._fk_compiled
        if compiled is None:
            T = self._joint_frames_numpy(batch)[:, -1]
        else:
            T = np.empty((batch.shape[0], 4, 4))
            compiled.frames(_plain_floats(batch), T[:, None])           # the tool's frame alone
        return T[0] if q.ndim == 1 else T

    def jacobian(self, q):
        """Geometric Jacobian of the tool, base frame, shape (6, dof): rows v (m/s) then w (rad/s)."""
        q = self.check_joints(q)
        frames = self.joint_frames(q[None] if q.ndim == 1 else q)[0]
        p_tool = frames[-1, :3, 3]
        J = np.zeros((6, self.dof))
        for i in range(self.dof):
            z = frames[i, :3, :3] @ self._axes[i]
            if self._prismatic[i]:
                J[:3, i] = z
            else:
                J[:3, i] = np.cross(z, p_tool - frames[i, :3, 3])
                J[3:, i] = z
        return J

    def jacobians(self, q):
        """Geometric Jacobians for many configurations, shape (N, 6, dof)."""
        return self._jacobians(self.joint_frames(np.atleast_2d(self.check_joints(q))))

    def _jacobians(self, frames):
        """Jacobians from the frames of :meth:`joint_frames`, shape (N, 6, dof)."""
        z = np.einsum('nijk,ik->nij', frames[:, :-1, :3, :3], self._axes)      # (N, dof, 3)
        lever = frames[:, -1:, :3, 3] - frames[:, :-1, :3, 3]
        J = np.zeros((frames.shape[0], 6, self.dof))
        rev = ~self._prismatic
        J[:, :3, rev] = np.swapaxes(np.cross(z[:, rev], lever[:, rev]), 1, 2)
        J[:, 3:, rev] = np.swapaxes(z[:, rev], 1, 2)
        J[:, :3, self._prismatic] = np.swapaxes(z[:, self._prismatic], 1, 2)
        return J

    def min_singular_values(self, q):
        """Smallest singular value of the Jacobian at each configuration, shape (N,).

        Rows used: position and orientation for 6+ joints, position only otherwise.
        """
        q = np.atleast_2d(self.check_joints(q))
        compiled = self._fk_compiled
        if compiled is None:
            return self._min_singular_values_numpy(q)
        out = np.empty(q.shape[0])
        compiled.min_singular_values(_plain_floats(q), 6 if self.dof >= 6 else 3, out)
        return out

    def _min_singular_values_numpy(self, q):
        J = self._jacobians(self._joint_frames_numpy(q))
        if self.dof < 6:
            J = J[:, :3]
        return np.linalg.svd(J, compute_uv=False)[:, -1]

    @functools.cached_property
    def _fk_compiled(self):
        """The compiled chain kernels (:class:`.fast_fk.Bound`), or None.

        Loaded on first use, and used only if they give the numpy versions' frames (the
        tool's alone too) and singular values for 64 configurations within the limits. None
        without numba, or (with a warning) if numba cannot compile or cache them here.
        """
        fast_fk = load(f'{__package__}.fast_fk', 'the compiled forward kinematics', 'they run vectorised with numpy')
        if fast_fk is None:
            return None
        bound = fast_fk.Bound(self)
        rng = np.random.default_rng(0)
        finite = np.isfinite(self.lower) & np.isfinite(self.upper)
        Q = rng.uniform(np.where(finite, self.lower, -np.pi), np.where(finite, self.upper, np.pi), (64, self.dof))
        frames, tools, sigma = np.empty((64, self.dof + 1, 4, 4)), np.empty((64, 1, 4, 4)), np.empty(64)
        bound.frames(Q, frames)
        bound.frames(Q, tools)
        bound.min_singular_values(Q, 6 if self.dof >= 6 else 3, sigma)
        numpy = self._joint_frames_numpy(Q)
        if not (np.allclose(frames, numpy, rtol=0.0, atol=1e-12) and np.array_equal(tools[:, 0], frames[:, -1])
                and np.allclose(sigma, self._min_singular_values_numpy(Q), rtol=0.0, atol=1e-9)):
            warnings.warn('the compiled forward kinematics disagree with the numpy version on their self-test: '
                          'they run vectorised with numpy', RuntimeWarning, stacklevel=2)
            return None
        return bound

    # -- inverse kinematics ------------------------------------------------
    def ik_all(self, T):
        """Every closed-form solution for pose ``T`` (before limits), shape (k, dof).

        Only for the closed-form solvers; the numeric one returns its best solution.
        """
        T = _check_pose(T)
        return self._solver.all_solutions(T[None])[0]

    def ik(self, T, seed=None):
        """The valid joint solution nearest ``seed`` for tool pose ``T``.

        Parameters
        ----------
        T : array_like, shape (4, 4)
            Tool pose in the base frame. Arms with fewer than 6 joints solve the
            position only (the rotation block is ignored).
        seed : array_like, shape (dof,), optional
            Current joints; default the middle of the limits.

        Returns
        -------
        ndarray, shape (dof,)

        Raises
        ------
        Unreachable
            With the reason: out of reach, beyond joint limits or singular.
        ValueError
            For non-finite or malformed input.
        """
        compiled = self._solver.compiled
        if compiled is not None:
            pose = _plain_floats(T)
            q0 = self._seed(None) if seed is None else _plain_floats(seed)
            if pose.shape == (4, 4) and q0.shape == (self.dof,):
                q = np.empty(self.dof)
                if compiled.one(pose, q0, q) == 0:
                    return q
        # Without the compiled path, or to say why it failed: the vectorised solver.
        T, seed = _check_pose(T), self._seed(seed)
        q, ok, reasons = self._solver.solve(T[None], seed[None])
        if not ok[0]:
            raise Unreachable(reasons[0])
        return q[0]

    def load_ik(self):
        """Load the compiled IK and forward kinematics now (else the first call that
        needs them does).

        Returns True if IK runs compiled, False if it runs the vectorised
        solver (numba missing, or an arm without a closed form).
        """
        self._fk_compiled
        return self._solver.compiled is not None

    def load_fk(self):
        """True if :meth:`joint_frames`, :meth:`fk` and :meth:`min_singular_values` run compiled."""
        return self._fk_compiled is not None

    def ik_batch(self, T, seed=None):
        """IK for many poses at once.

        Parameters
        ----------
        T : array_like, shape (N, 4, 4)
        seed : array_like, shape (dof,) or (N, dof), optional

        Returns
        -------
        q : ndarray, shape (N, dof)
            NaN rows where no valid solution exists.
        ok : ndarray of bool, shape (N,)
        reasons : list of str
            Why each failed ('' where ok).
        """
        T = np.asarray(T, dtype=float)
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError('T must be a finite array of poses, shape (N, 4, 4)')
        seed = np.broadcast_to(self._seed(seed), (T.shape[0], self.dof))
        compiled = self._solver.compiled
        if compiled is None:
            return self._solver.solve(T, seed)
        q, status = np.empty((T.shape[0], self.dof)), np.empty(T.shape[0], dtype=np.int64)
        compiled.many(_plain_floats(T), _plain_floats(seed), q, status)
        ok = status == 0
        reasons = [''] * len(T)
        failed = np.flatnonzero(~ok)
        if failed.size:
            # The vectorised solver says why (and answers as it would for poses the kernel refuses).
            q[failed], ok[failed], why = self._solver.solve(T[failed], seed[failed])
            for i, reason in zip(failed, why):
                reasons[i] = reason
        return q, ok, reasons

    def _seed(self, seed):
        if seed is None:
            mid = np.where(np.isfinite(self.lower + self.upper), 0.5 * (self.lower + self.upper), 0.0)
            return mid
        return self.check_joints(seed, 'seed')

    # -- reachability (the paper's step C) ------------------------------------
    def check_reachable(self, T, seed=None):
        """Step C of Sec. 3.1: refuse a target outside the workspace before planning.

        Returns the IK solution nearest ``seed`` when the target is reachable;
        raises :class:`Unreachable` with the reason otherwise.
        """
        T = _check_pose(T)
        reason = self._solver.quick_reject(T)
        if reason:
            raise Unreachable(reason)
        return self.ik(T, seed)

    @property
    def reach(self):
        """(inner, outer) radius of the reach shell about the shoulder, m (closed-form arms)."""
        return self._solver.reach


def _plain_floats(x):
    """``x`` as a writable, aligned, C-contiguous float64 array (no copy when it is one already):
    the one signature of the compiled IK."""
    a = np.ascontiguousarray(x, dtype=float)
    flags = a.flags
    return a if flags.writeable and flags.aligned else a.copy()


def _check_pose(T):
    """A finite 4x4 pose with a proper rotation block, else ValueError (in plain floats: fast)."""
    if not (isinstance(T, np.ndarray) and T.dtype == np.float64):
        T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f'pose must be a 4x4 homogeneous transform, got shape {T.shape}')
    rows = T.tolist()
    a, b, c, d = rows
    # One sum is finite only if every term is (a NaN or inf anywhere poisons it).
    if not math.isfinite(sum(a) + sum(b) + sum(c) + sum(d)):
        raise ValueError('pose must be finite')
    a0, a1, a2 = a[0], a[1], a[2]
    b0, b1, b2 = b[0], b[1], b[2]
    c0, c1, c2 = c[0], c[1], c[2]
    worst = max(abs(a0 * a0 + a1 * a1 + a2 * a2 - 1.0), abs(b0 * b0 + b1 * b1 + b2 * b2 - 1.0),
                abs(c0 * c0 + c1 * c1 + c2 * c2 - 1.0), abs(a0 * b0 + a1 * b1 + a2 * b2),
                abs(a0 * c0 + a1 * c1 + a2 * c2), abs(b0 * c0 + b1 * c1 + b2 * c2))
    det = a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)
    if worst > 1e-6 or det < 0:
        raise ValueError('pose rotation block must be a proper rotation matrix')
    return T


def load_joint_limits(path):
    """Read a MoveIt-style joint_limits.yaml (safe loader: no code runs). Values tagged ``!degrees`` (as
    Universal Robots' files write them) are read in degrees and given in radians."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def degrees(loader, node):
        value = loader.construct_scalar(node)
        try:
            return math.radians(float(value))
        except ValueError:
            raise ValueError(f'{path}: !degrees needs a number, got {value!r}') from None

    Loader.add_constructor('!degrees', degrees)
    with open(path) as f:
        data = yaml.load(f, Loader=Loader) or {}      # noqa: S506 - a SafeLoader with one numeric tag
    if not isinstance(data, dict):
        raise ValueError(f'{path}: expected a mapping with joint_limits')
    return data
