"""The shipped UR5e and FR3: their kinematics, IK (closed form for the UR family, numeric for any chain), limits."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core import kinematics
from picking_core.kinematics import Unreachable, pose_matrix
from picking_description import urdf_path

# Universal Robots' published Denavit-Hartenberg parameters of the UR5e (m, rad).
D = (0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996)
A = (0.0, -0.425, -0.3922, 0.0, 0.0, 0.0)
ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
GRASP = 0.15          # tool0 beyond the flange


def dh_fk(q):
    """The UR5e's tool0 by the textbook product of Denavit-Hartenberg transforms."""
    T = np.eye(4)
    for theta, d, a, alpha in zip(q, D, A, ALPHA):
        ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
    return T @ pose_matrix([0.0, 0.0, GRASP])


def test_the_ur5e_is_the_published_geometry(ur5e):
    assert ur5e.solver == 'offset_wrist'
    assert ur5e.joint_names == ('shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint',
                                'wrist_1_joint', 'wrist_2_joint', 'wrist_3_joint')
    assert ur5e.extra_joint_names == ('gripper_joint',)
    assert ur5e.max_velocity == pytest.approx(np.full(6, np.pi))
    assert np.isfinite(ur5e.max_acceleration).all() and np.isfinite(ur5e.max_jerk).all()
    # Stretched out along -x at the shoulder's height, the flange facing -y.
    assert ur5e.fk(np.zeros(6))[:3, 3] == pytest.approx([-0.8172, -0.1333 - 0.0996 - GRASP, 0.1625 - 0.0997],
                                                         abs=1e-12)
    Q = np.random.default_rng(0).uniform(ur5e.lower, ur5e.upper, (200, 6))
    assert ur5e.fk(Q) == pytest.approx(np.stack([dh_fk(q) for q in Q]), abs=1e-12)


def test_ik_of_fk_for_10000_random_configurations_to_a_nanometre(ur5e):
    rng = np.random.default_rng(2026)
    Q = rng.uniform(ur5e.lower, ur5e.upper, (10_000, 6))
    T = ur5e.fk(Q)
    seeds = np.clip(Q + rng.normal(0.0, 0.05, Q.shape), ur5e.lower, ur5e.upper)
    q, ok, reasons = ur5e.ik_batch(T, seeds)
    assert ok.all(), set(reasons)
    assert np.all(ur5e.within_limits(q))
    F = ur5e.fk(q)
    assert np.abs(F[:, :3, 3] - T[:, :3, 3]).max() <= 1e-9
    angle = Rotation.from_matrix(np.swapaxes(F[:, :3, :3], 1, 2) @ T[:, :3, :3]).magnitude()
    assert angle.max() <= 1e-9
    nearest = np.sum((q - seeds) ** 2, axis=1)
    assert np.all(nearest <= np.sum((Q - seeds) ** 2, axis=1) + 1e-9)
    exact, _, _ = ur5e.ik_batch(T, Q)
    assert np.abs(exact - Q).max() < 1e-8


def test_a_general_pose_has_eight_solutions(ur5e):
    q_true = np.array([0.4, -1.1, 1.3, -0.7, 1.2, 0.3])
    T = ur5e.fk(q_true)
    solutions = ur5e.ik_all(T)
    assert solutions.shape == (8, 6)
    assert ur5e.fk(solutions) == pytest.approx(np.broadcast_to(T, (8, 4, 4)), abs=1e-9)
    wrapped = np.mod(solutions + np.pi, 2 * np.pi)
    assert len({tuple(np.round(s, 6)) for s in wrapped}) == 8
    assert ur5e.ik(T, q_true + 0.02) == pytest.approx(q_true, abs=1e-9)


def test_a_singular_wrist_keeps_wrist_3_at_the_seed(ur5e):
    q_true = np.array([0.3, -1.2, 1.0, 0.2, 0.0, 0.5])           # wrist 2 at zero: wrists 1 and 3 aligned
    seed = q_true + 0.01
    q = ur5e.ik(ur5e.fk(q_true), seed)
    assert q[5] == pytest.approx(seed[5], abs=1e-12)
    assert ur5e.fk(q) == pytest.approx(ur5e.fk(q_true), abs=1e-9)


@pytest.mark.parametrize('position, why', [
    ([1.5, 0.0, 0.3], 'no shoulder and elbow angles'),
    ([0.0, 0.0, 0.6], 'closer than the shoulder offset'),
])
def test_out_of_reach_says_why(ur5e, position, why):
    with pytest.raises(Unreachable, match=f'out of reach: .*{why}'):
        ur5e.ik(pose_matrix(position, Rotation.from_euler('x', 180, degrees=True).as_quat()))


def test_the_vendors_frames_get_the_closed_form_too():
    """A UR description with its base turned half a turn and its tool frame turned (as Universal
    Robots' own description has them) reads into the same closed form."""
    urdf = urdf_path('ur5e').read_text()
    urdf = urdf.replace('<parent link="base_link"/><child link="shoulder_link"/>',
                        '<parent link="base_link_inertia"/><child link="shoulder_link"/>')
    urdf = urdf.replace('<link name="shoulder_link">', '''<link name="base_link_inertia"/>
  <joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/>
    <child link="base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/></joint>
  <link name="shoulder_link">''')
    urdf = urdf.replace('<origin xyz="0 0 0.15" rpy="0 0 0"/>', '<origin xyz="0.01 0 0.15" rpy="1.5707963 0 1.5707963"/>')
    arm = kinematics.ArmModel.from_urdf_string(urdf, joint_limits=kinematics.load_joint_limits(
        urdf_path('ur5e').with_name('ur5e_joint_limits.yaml')))
    assert arm.solver == 'offset_wrist'
    rng = np.random.default_rng(3)
    Q = rng.uniform(arm.lower, arm.upper, (2000, 6))
    T, seeds = arm.fk(Q), Q + 0.01
    q, ok, _ = arm.ik_batch(T, seeds)
    assert ok.all() and arm.fk(q) == pytest.approx(T, abs=1e-9)
    assert np.all(np.sum((q - seeds) ** 2, axis=1) <= np.sum((Q - seeds) ** 2, axis=1) + 1e-9)


def test_an_arm_whose_waist_misses_the_shoulder_axis_gets_the_numeric_solver():
    urdf = urdf_path('ur5e').read_text().replace('<origin xyz="0 0 0" rpy="1.5707963267948966 0 0"/>',
                                                 '<origin xyz="0.05 0 0" rpy="1.5707963267948966 0 0"/>')
    assert kinematics.ArmModel.from_urdf_string(urdf).solver == 'numeric'


# Franka's published kinematics of the FR3 (Craig's modified Denavit-Hartenberg: a_{i-1}, d_i, alpha_{i-1}).
FR3 = ((0.0, 0.333, 0.0), (0.0, 0.0, -np.pi / 2), (0.0, 0.316, np.pi / 2), (0.0825, 0.0, np.pi / 2),
       (-0.0825, 0.384, -np.pi / 2), (0.0, 0.0, np.pi / 2), (0.088, 0.0, np.pi / 2))
FR3_FLANGE = 0.107


@pytest.fixture(scope='module')
def fr3():
    return kinematics.ArmModel.from_urdf(urdf_path('fr3'))


def fr3_fk(q):
    T = np.eye(4)
    for theta, (a, d, alpha) in zip(q, FR3):
        T = T @ pose_matrix([a, 0, 0], Rotation.from_euler('x', alpha).as_quat()) \
              @ pose_matrix([0, 0, d], Rotation.from_euler('z', theta).as_quat())
    return T @ pose_matrix([0.0, 0.0, FR3_FLANGE + GRASP])


def test_the_fr3_is_the_published_geometry(fr3):
    assert fr3.dof == 7 and fr3.solver == 'numeric' and fr3.load_ik()
    assert fr3.max_acceleration == pytest.approx(np.full(7, 10.0))
    Q = np.random.default_rng(0).uniform(fr3.lower, fr3.upper, (200, 7))
    assert fr3.fk(Q) == pytest.approx(np.stack([fr3_fk(q) for q in Q]), abs=1e-12)


def test_fr3_numeric_ik_solves_random_reachable_poses_and_never_calls_them_out_of_reach(fr3):
    rng = np.random.default_rng(11)
    Q = rng.uniform(fr3.lower, fr3.upper, (1000, 7))
    T = fr3.fk(Q)
    q, ok, reasons = fr3.ik_batch(T)                                   # from the default seed
    assert ok.mean() >= 0.995
    assert all(r.startswith('no solution found') for r, k in zip(reasons, ok) if not k)
    F = fr3.fk(q[ok])
    assert np.abs(F[:, :3, 3] - T[ok, :3, 3]).max() < 1e-9 and np.all(fr3.within_limits(q[ok]))
    # From nearby seeds the redundant joint stays near the seed.
    seeds = np.clip(Q + rng.normal(0.0, 0.05, Q.shape), fr3.lower, fr3.upper)
    q, ok, _ = fr3.ik_batch(T, seeds)
    assert ok.all()
    assert np.median(np.abs(q - seeds).max(axis=1)) < 0.2


def test_fr3_out_of_reach_only_when_proven(fr3):
    with pytest.raises(Unreachable, match='out of reach: the tool would be 3.0.. m from the first joint'):
        fr3.ik(pose_matrix([3.0, 0.0, 0.333]))
    # Within the chain's length but below the floor the arm cannot bend to: not found, not "out of reach".
    with pytest.raises(Unreachable, match='no solution found'):
        fr3.ik(pose_matrix([0.0, 0.0, -0.5]))


def test_the_numeric_ik_without_numba_runs_the_same_method(fr3, monkeypatch):
    solver = fr3._solver
    monkeypatch.setattr(solver, 'compiled', None)
    rng = np.random.default_rng(12)
    Q = rng.uniform(fr3.lower, fr3.upper, (20, 7))
    q, ok, _ = solver.solve(fr3.fk(Q), np.clip(Q + 0.05, fr3.lower, fr3.upper))
    assert ok.mean() >= 0.9 and fr3.fk(q[ok]) == pytest.approx(fr3.fk(Q[ok]), abs=1e-9)


def test_joint_limits_in_degrees_as_universal_robots_write_them(tmp_path):
    limits = tmp_path / 'joint_limits.yaml'
    limits.write_text('joint_limits:\n  elbow_joint:\n    has_velocity_limits: true\n    max_velocity: !degrees 180.0\n'
                      '    has_position_limits: true\n    min_position: !degrees -90\n    max_position: !degrees 90\n')
    arm = kinematics.ArmModel.from_urdf(urdf_path('ur5e'), joint_limits=limits)
    i = arm.joint_names.index('elbow_joint')
    assert arm.max_velocity[i] == pytest.approx(np.pi) and arm.upper[i] == pytest.approx(np.pi / 2)
    limits.write_text('joint_limits:\n  elbow_joint:\n    max_velocity: !degrees fast\n')
    with pytest.raises(ValueError, match='!degrees needs a number'):
        kinematics.load_joint_limits(limits)


def test_missing_acceleration_and_jerk_limits_are_named():
    arm = kinematics.ArmModel.from_urdf(urdf_path('ur5e'), joint_limits={})
    assert arm.missing_limits() == ('ur5e has no acceleration limit for shoulder_pan_joint, shoulder_lift_joint, '
                                    'elbow_joint, wrist_1_joint, wrist_2_joint, wrist_3_joint, gripper_joint; no jerk '
                                    'limit for shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_1_joint, '
                                    'wrist_2_joint, wrist_3_joint')
    for name in ('picking_arm', 'ur5e', 'fr3'):
        assert kinematics.ArmModel.from_urdf(urdf_path(name)).missing_limits() == ''


def test_a_home_with_the_tool_below_the_base_is_refused(ur5e):
    from picking_core.pick_cycle import PickSettings
    with pytest.raises(ValueError, match=r'put the tool 0\.\d+ m below the arm\'s base'):
        PickSettings(home_positions=(0.0, 0.2, 1.6, 0.0, -0.23, 0.0)).validate(ur5e)   # the default arm's home


@pytest.mark.parametrize('name, shoulder', [('picking_arm', 1), ('ur5e', 1), ('fr3', 1)])
def test_the_transfer_lifts_the_shoulder_found_from_the_geometry(name, shoulder):
    from picking_core.pick_cycle import PickCycle
    from picking_core.planning import Planner
    arm = kinematics.ArmModel.from_urdf(urdf_path(name))
    cycle = PickCycle(Planner(arm))
    assert cycle._shoulder == shoulder
    q = arm.lower * 0.0 + np.clip(0.3, arm.lower, arm.upper)
    via = cycle._clearance(q, q)
    assert arm.fk(via)[2, 3] > arm.fk(q)[2, 3]                  # the tool rises


def _write_stl(path, vertices, faces):
    """A binary STL of the triangles ``faces`` (indices into ``vertices``), m."""
    import struct
    with open(path, 'wb') as f:
        f.write(b'\0' * 80 + struct.pack('<I', len(faces)))
        for tri in faces:
            f.write(struct.pack('<3f', 0.0, 0.0, 0.0))
            for i in tri:
                f.write(struct.pack('<3f', *vertices[i]))
            f.write(b'\0\0')


def _tube(radius, length, n=16):
    """A closed tube along x, from 0 to ``length``: its vertices and triangles."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.zeros(n), radius * np.cos(a), radius * np.sin(a)], axis=1)
    vertices = np.vstack([ring, ring + [length, 0.0, 0.0]])
    faces = [(i, (i + 1) % n, n + i) for i in range(n)] + [((i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    faces += [(0, i, i + 1) for i in range(1, n - 1)] + [(n, n + i + 1, n + i) for i in range(1, n - 1)]
    return vertices, faces


def test_mesh_and_box_links_are_bounded_by_capsules_that_hold_them(tmp_path, monkeypatch):
    from picking_core.kinematics.capsules import ArmCapsules
    from picking_core.kinematics.urdf import parse_collisions
    vertices, faces = _tube(0.05, -0.3922)
    (tmp_path / 'my_arm' / 'meshes').mkdir(parents=True)
    _write_stl(tmp_path / 'my_arm' / 'meshes' / 'forearm.stl', vertices, faces)
    _write_stl(tmp_path / 'wrist.stl', *_tube(0.04, 0.1))
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path))
    urdf = urdf_path('ur5e').read_text()
    forearm = ('<collision><origin xyz="-0.1961 0 0.007" rpy="0 1.5707963267948966 0"/><geometry><cylinder '
               'radius="0.045" length="0.3922"/></geometry></collision>')
    assert forearm in urdf
    urdf = urdf.replace(forearm, '<collision><origin xyz="0 0 0.007"/><geometry>'
                                 '<mesh filename="package://my_arm/meshes/forearm.stl"/></geometry></collision>')
    urdf = urdf.replace('<collision><geometry><cylinder radius="0.045" length="0.1"/></geometry></collision>',
                        '<collision><geometry><mesh filename="wrist.stl" scale="1 1 1"/></geometry></collision>'
                        '<collision><geometry><box size="0.05 0.05 0.2"/></geometry></collision>', 1)
    (tmp_path / 'arm.urdf').write_text(urdf)
    arm = kinematics.ArmModel.from_urdf(tmp_path / 'arm.urdf', joint_limits=urdf_path('ur5e').with_name(
        'ur5e_joint_limits.yaml'))
    shapes = {c.link: c for c in reversed(parse_collisions(arm.urdf, arm.urdf_dir))}
    mesh = shapes['forearm_link']
    inside = (np.linalg.inv(mesh.origin) @ np.c_[vertices + [0, 0, 0.007], np.ones(len(vertices))].T)[:3].T
    z = np.clip(inside[:, 2], -mesh.length / 2, mesh.length / 2)
    gap = np.linalg.norm(inside - np.c_[np.zeros((len(z), 2)), z], axis=1)
    assert gap.max() <= mesh.radius + 1e-6                          # every vertex inside
    assert mesh.radius == pytest.approx(0.05, abs=2e-3) and mesh.length == pytest.approx(0.3922, abs=0.02)
    capsules = ArmCapsules.from_arm(arm)
    assert {'forearm_link', 'wrist_1_link'} <= set(capsules.links)
    missing = urdf.replace('package://my_arm/meshes/forearm.stl', 'package://my_arm/meshes/gone.stl')
    with pytest.raises(ValueError, match="mesh 'package://my_arm/meshes/gone.stl' not found"):
        parse_collisions(missing, tmp_path)


def test_a_box_link_is_checked_as_the_box_not_its_bounding_capsule(tmp_path):
    """A flat plate as the forearm: an obstacle beside its face but inside its capsule is clear, one within the
    clearance of the face is a contact, in the narrow phase (coal's hull) and in the whole-trajectory check."""
    from picking_core.collision import CollisionChecker
    from picking_core.collision.scene import Scene, rod
    from picking_core.kinematics.capsules import ArmCapsules
    urdf = urdf_path('ur5e').read_text()
    forearm = ('<collision><origin xyz="-0.1961 0 0.007" rpy="0 1.5707963267948966 0"/><geometry><cylinder '
               'radius="0.045" length="0.3922"/></geometry></collision>')
    plate = ('<collision><origin xyz="-0.1961 0 0.007" rpy="0 1.5707963267948966 0"/><geometry>'
             '<box size="0.05 0.3 0.3922"/></geometry></collision>')
    (tmp_path / 'arm.urdf').write_text(urdf.replace(forearm, plate))
    arm = kinematics.ArmModel.from_urdf(tmp_path / 'arm.urdf', joint_limits=urdf_path('ur5e').with_name(
        'ur5e_joint_limits.yaml'))
    capsules = ArmCapsules.from_arm(arm)
    k = capsules.links.index('forearm_link')
    assert capsules.radius[k] == pytest.approx(np.hypot(0.025, 0.15), abs=1e-6)     # the plate's half diagonal
    q = np.array([3.14, -2.04, 2.02, 0.02, 1.57, -1.57])
    T = capsules.frames(q)[0, k]
    points = capsules.hulls[k] @ T[:3, :3].T + T[:3, 3]
    centre = points.mean(axis=0)
    # The plate's thin direction: its smallest extent through the centre.
    normal = np.linalg.svd(points - centre)[2][-1]
    along = np.linalg.svd(points - centre)[2][0]

    def wire_at(gap):                                # a thin wire across the plate, ``gap`` m off its face
        middle = centre + normal * (0.025 + 0.003 + gap)
        return Scene((rod('wire', 'wire', middle - 0.5 * along, middle + 0.5 * along, 0.003),))

    for gap, touching in ((0.05, False), (0.01, True)):
        checker = CollisionChecker(capsules, wire_at(gap), clearance=0.02, self_check=False)
        assert 0.05 < capsules.radius[k] + 0.02 - (0.025 + 0.003)       # the bounding capsule would touch both
        assert bool(checker.colliding(q[None])[0]) is touching, gap
        found = checker.contacts(q[None])[0]
        assert (found is not None and found.link == 'forearm_link') is touching
