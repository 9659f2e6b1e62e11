"""``picking-plan``: plan any of the paper's methods offline, write CSV and plots.

No ROS graph is needed. Examples::

    picking-plan lspb --q0 15 --qf 75 --duration 3 --accel 42 --deg
    picking-plan cubic --q0 0 0 --qf 1.2 -0.5 --duration 2
    picking-plan via-lspb --points 15 75 30 60 --durations 3 2 2 --accel 200 --deg
    picking-plan quintic-via --points 0,0 1,0.5 0,1 --durations 2
    picking-plan arc --p1 10 3 4 --p2 11 3 5 --p3 10 3 6 --n 45
    picking-plan --paper --out out/paper
    picking-plan workspace --urdf src/picking_description/urdf/picking_arm.urdf

A via point with several joints is written ``q1,q2,...``. With ``--deg`` the
joint values given are degrees and the CSV and plots are in degrees too;
otherwise radians (or metres for prismatic joints).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from picking_core import geometry, trajectory

PAPER_LSPB = dict(q0=15.0, qf=75.0, duration=3.0)
PAPER_ARC = ((10.0, 3.0, 4.0), (11.0, 3.0, 5.0), (10.0, 3.0, 6.0))
PAPER_VIA = dict(
    points=[[0, 0, 0], [-11.2, 9.4, -109.6], [13.2, -10.8, -99.3], [0, 0, 0]],
    velocities=[[0, 0, 0], [-9.3, 13.4, 134.1], [-15.4, 16.2, 164.2], [0, 0, 0]],
    accelerations=[[0, 0, 0], [-13.5, 27.4, 104.3], [-17.2, 21.1, 114.7], [0, 0, 0]],
    durations=2.0,
)
CHORD_COUNTS = (5, 10, 20, 47, 50, 100, 200, 500, 1000)


def write_csv(path, t, q, qd, qdd):
    """``t`` then ``q``, ``qd``, ``qdd`` per joint, one row per sample."""
    n = q.shape[1]
    header = ['t'] + [f'{name}{j + 1}' for name in ('q', 'qd', 'qdd') for j in range(n)]
    with open(path, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(np.column_stack((t, q, qd, qdd)).round(10).tolist())
    return Path(path)


def _sample_grid(duration, dt):
    n = int(np.floor(duration / dt + 1e-9)) + 1
    t = np.arange(n) * dt
    return t if t[-1] >= duration - 1e-12 else np.append(t, duration)


def save_profile(traj, out, stem, title, unit, dt, labels=None):
    """Sample ``traj`` every ``dt`` s; write ``stem.csv`` and ``stem.png`` (``labels``: a name per column, by
    default "joint 1", ...); return the paths."""
    t = _sample_grid(traj.duration, dt)
    q, qd, qdd = traj.sample(t)
    csv_path = write_csv(out / f'{stem}.csv', t, q, qd, qdd)
    from .plots import plot_profiles
    png = plot_profiles(out / f'{stem}.png', t, q, qd, qdd, title, unit, labels=labels,
                        marks=traj.breaks[1:-1] if len(traj.breaks) < 40 else ())
    return [csv_path, png]


def save_arc(arc, n_insert, out, stem='arc'):
    """The arc with ``n_insert`` interpolation points between P1 and P3 (Fig. 13)."""
    from .plots import plot_path_3d
    pts = arc.points(n_insert + 2)
    dense = arc.points(400)
    with open(out / f'{stem}_points.csv', 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(['i', 'x', 'y', 'z'])
        writer.writerows([[i, *p] for i, p in enumerate(np.round(pts, 10).tolist())])
    png = plot_path_3d(out / f'{stem}.png', {'arc': dense}, pts,
                       f'Arc through P1, P2, P3: {n_insert} insertion points between P1 and P3, r = {arc.radius:.4g}',
                       {'P1': arc.p1, 'P2': arc.p2, 'P3': arc.p3})
    return [out / f'{stem}_points.csv', png]


def chord_error_table(arc, counts=CHORD_COUNTS):
    """Sec. 3.2: the largest distance between the polyline of N points and the arc.

    Measured on a dense sampling of the arc against each chord, and compared with
    the sagitta formula of :meth:`Arc.chord_error`. Returns rows (N, measured, formula).
    """
    rows = []
    for n in counts:
        knots = arc.points(n)
        k = 64
        u = (np.arange(k) + 0.5) / k
        s = (np.arange(n - 1)[:, None] + u[None, :]).ravel() * arc.length / (n - 1)
        on_arc = arc.at(s)[0].reshape(n - 1, k, 3)
        a, b = knots[:-1, None, :], knots[1:, None, :]
        ab = b - a
        w = np.clip(np.einsum('ijk,ijk->ij', on_arc - a, ab) / np.einsum('ijk,ijk->ij', ab, ab), 0, 1)
        dist = np.linalg.norm(on_arc - (a + w[..., None] * ab), axis=2).max()
        rows.append((n, float(dist), float(arc.chord_error(n))))
    return rows


def save_chord_table(arc, out):
    from .plots import plot_loglog
    rows = chord_error_table(arc)
    with open(out / 'chord_error.csv', 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(['points', 'max_distance_measured', 'max_distance_formula'])
        writer.writerows(rows)
    png = plot_loglog(out / 'chord_error.png', [r[0] for r in rows], [r[1] for r in rows],
                      'interpolation points N', 'largest distance to the arc',
                      'Sec. 3.2: denser interpolation approaches the arc')
    return rows, [out / 'chord_error.csv', png]


def run_paper(out, dt):
    """Every example of the paper into ``out``; returns printable summary lines."""
    lines, files = [], []
    deg = 'deg'
    amin = trajectory.min_lspb_accel(**PAPER_LSPB)[0]
    lines.append(f'Eq. 20  LSPB 15->75 deg in 3 s: minimum acceleration {amin:.2f} deg/s^2')
    for accel, stem in ((42.0, 'fig9-11_lspb_42'), (27.0, 'fig9-11_lspb_27')):
        seg = trajectory.lspb(**PAPER_LSPB, accel=accel)
        lines.append(f'Eq. 19  accel {accel:g}: blend {seg.blend_time:.3f} s, blend end '
                     f'{seg.blend_position:.2f} deg, cruise {seg.cruise_velocity:.2f} deg/s')
        files += save_profile(seg, out, stem, f'LSPB 15→75° in 3 s, {accel:g}°/s² (Figs. 9-11)', deg, dt)
    both = trajectory.lspb([15.0, 15.0], [75.0, 75.0], 3.0, [42.0, 27.0])
    files += save_profile(both, out, 'fig9-11_lspb_both', 'LSPB 15→75° in 3 s: 42 and 27°/s²', deg, dt,
                          labels=['blend acceleration 42°/s²', 'blend acceleration 27°/s²'])
    for qf, stem in ((75.0, 'cubic_15_75'), (90.0, 'fig5_cubic_0_90')):
        q0 = 15.0 if qf == 75.0 else 0.0
        seg = trajectory.cubic(q0, qf, 3.0)
        c = seg.coeffs[0, :4, 0]
        t = np.linspace(0, 3, 3001)
        qd = seg.sample(t)[1][:, 0]
        lines.append(f'Eq. 11  cubic {q0:g}->{qf:g} deg in 3 s: a2 = {c[2]:.2f}, a3 = {c[3]:.2f}, '
                     f'peak velocity {qd.max():.2f} deg/s at {t[qd.argmax()]:.2f} s')
        files += save_profile(seg, out, stem, f'Cubic {q0:g}→{qf:g}° in 3 s (Eq. 12-13)', deg, dt)
    lines.append('        (the paper prints a2 = 2.35, a3 = -1.63 for 0->90 deg (Eq. 14); its own Eq. 11 '
                 'gives 30 and -6.67)')
    arc = geometry.Arc.through(*PAPER_ARC)
    lines.append(f'Sec. 3.1 arc P1 P2 P3: centre {np.round(arc.center, 6).tolist()}, radius '
                 f'{arc.radius:.6g}, sweep {np.degrees(arc.sweep):.1f} deg, 45 insertion points')
    files += save_arc(arc, 45, out, 'fig13_arc')
    rows, chord_files = save_chord_table(arc, out)
    files += chord_files
    lines.append('Sec. 3.2 largest polyline-to-arc distance: ' + ', '.join(
        f'N={n}: {d:.2e}' for n, d, _ in rows if n in (5, 47, 100, 1000)))
    via = trajectory.quintic_via(PAPER_VIA['points'], PAPER_VIA['durations'],
                                 PAPER_VIA['velocities'], PAPER_VIA['accelerations'])
    # The paper gives these wrist angles no unit; as its other joint examples, and at their size, degrees.
    files += save_profile(via, out, 'fig14_via_points', 'Sec. 3.1 D: X0 → Xf1 → Xf2 → X0, 2 s each', 'deg', dt)
    lines.append(f'Sec. 3.1 D via points: {via.duration:g} s, sampled every {dt:g} s, '
                 'all boundary conditions met')
    vl = trajectory.via_lspb(np.array(PAPER_VIA['points'], float), PAPER_VIA['durations'], 400.0)
    files += save_profile(vl, out, 'fig12_via_lspb', 'Fig. 12: via-point LSPB through the Sec. 3.1 D points, '
                          '400°/s²', 'deg', dt)
    return lines, files


def _vector_list(values, name):
    """Parse ``1,2,3 4,5,6`` (or plain numbers, one joint) into an (m, n) array."""
    try:
        rows = [[float(x) for x in v.split(',')] for v in values]
    except ValueError as exc:
        raise SystemExit(f'picking-plan: {name}: {exc}')
    if len({len(r) for r in rows}) != 1:
        raise SystemExit(f'picking-plan: {name}: every via point needs the same number of joints')
    return np.array(rows)


#: The options picking-plan takes before or after its method (`picking-plan lspb ... --deg`).
OPTIONS = {'paper': False, 'out': Path('out/plan'), 'dt': 0.01, 'deg': False, 'rad': False}


def build_parser():
    # (Given on both sides of the method; SUPPRESS keeps one side's value from hiding the other's.)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument('--paper', action='store_true', default=argparse.SUPPRESS,
                        help='reproduce every example of the paper')
    common.add_argument('--out', type=Path, default=argparse.SUPPRESS, help='output folder (default out/plan)')
    common.add_argument('--dt', type=float, default=argparse.SUPPRESS, help='sample period, s (default 0.01)')
    units = common.add_mutually_exclusive_group()
    units.add_argument('--deg', action='store_true', default=argparse.SUPPRESS, help='joint values in degrees')
    units.add_argument('--rad', action='store_true', default=argparse.SUPPRESS,
                       help='joint values in radians (default)')
    parser = argparse.ArgumentParser(
        prog='picking-plan', description=__doc__.split('\n\n')[0], parents=[common],
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split('\n\n', 1)[1])
    sub = parser.add_subparsers(dest='method')

    def add(name, **kw):
        return sub.add_parser(name, parents=[common], **kw)
    for name in ('cubic', 'quintic'):
        p = add(name, help=f'{name} polynomial move')
        p.add_argument('--q0', type=float, nargs='+', required=True, help='start, one value per joint')
        p.add_argument('--qf', type=float, nargs='+', required=True, help='end, one value per joint')
        p.add_argument('--duration', type=float, required=True, help='s')
        p.add_argument('--v0', type=float, nargs='+', default=None, help='start velocity per joint (default: rest)')
        p.add_argument('--vf', type=float, nargs='+', default=None, help='end velocity per joint (default: rest)')
    p = add('lspb', help='linear segment with parabolic blends (Eq. 15-20)')
    p.add_argument('--q0', type=float, nargs='+', required=True)
    p.add_argument('--qf', type=float, nargs='+', required=True)
    p.add_argument('--duration', type=float, required=True, help='s')
    p.add_argument('--accel', type=float, nargs='+', required=True, help='blend acceleration per s^2')
    p = add('via-lspb', help='LSPB through via points (Fig. 12)')
    p.add_argument('--points', nargs='+', required=True, help='via points, each q1,q2,...')
    p.add_argument('--durations', type=float, nargs='+', required=True, help='s per segment')
    p.add_argument('--accel', type=float, nargs='+', required=True)
    p = add('quintic-via', help='quintics through via points (Sec. 3.1 D)')
    p.add_argument('--points', nargs='+', required=True, help='via points, each q1,q2,...')
    p.add_argument('--durations', type=float, nargs='+', required=True, help='s per segment')
    p.add_argument('--velocities', nargs='+', help='velocity at each via point, each v1,v2,...')
    p.add_argument('--accelerations', nargs='+', help='acceleration at each via point')
    p = add('arc', help='spatial arc through three points (Sec. 2.3)')
    for k in ('p1', 'p2', 'p3'):
        p.add_argument(f'--{k}', type=float, nargs=3, required=True, metavar=('X', 'Y', 'Z'))
    p.add_argument('--n', type=int, default=45, help='insertion points between p1 and p3')
    p.add_argument('--duration', type=float, default=2.0, help='traversal time, s')
    p.add_argument('--profile', choices=geometry.PROFILES, default='quintic')
    p = add('workspace', help="plot the arm's reachable workspace (reach shell and limits)")
    p.add_argument('--urdf', type=Path, default=None, help='arm model (default: picking_description/urdf/picking_arm.urdf)')
    p.add_argument('--samples', type=int, default=20000, help='random configurations within the limits')
    return parser


def save_workspace(urdf, samples, out):
    """Side and top views of tool positions over random joint values within the limits."""
    from picking_core.kinematics import ArmModel
    from picking_description import default_urdf

    from .plots import plot_workspace
    arm = ArmModel.from_urdf(urdf or default_urdf())
    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(arm.lower), arm.lower, -np.pi)
    hi = np.where(np.isfinite(arm.upper), arm.upper, np.pi)
    tool = arm.fk(rng.uniform(lo, hi, (samples, arm.dof)))[:, :3, 3]
    png = plot_workspace(out / 'workspace.png', tool, arm)
    return arm, tool, [png]


def plan_from_args(args):
    """The trajectory the arguments ask for (angles converted to radians unless --deg)."""
    m = args.method
    if m in ('cubic', 'quintic'):
        rest = [0.0] * len(args.q0)                   # the default: from rest to rest, for any number of joints
        return getattr(trajectory, m)(args.q0, args.qf, args.duration, args.v0 or rest, args.vf or rest)
    if m == 'lspb':
        return trajectory.lspb(args.q0, args.qf, args.duration, args.accel)
    points = _vector_list(args.points, '--points')
    durations = args.durations[0] if len(args.durations) == 1 else args.durations
    if m == 'via-lspb':
        return trajectory.via_lspb(points, durations, args.accel)
    vel = _vector_list(args.velocities, '--velocities') if args.velocities else None
    acc = _vector_list(args.accelerations, '--accelerations') if args.accelerations else None
    return trajectory.quintic_via(points, durations, vel, acc)


def degrees_hint(args):
    """A note when joint values given in radians look like degrees (beyond one turn)."""
    if args.deg or args.method not in ('cubic', 'quintic', 'lspb', 'via-lspb', 'quintic-via'):
        return None
    given = [v for name in ('q0', 'qf') for v in (getattr(args, name, None) or [])]
    for text in getattr(args, 'points', None) or []:
        given += [float(x) for x in text.split(',') if x.strip()]
    if given and max(abs(v) for v in given) > 2 * np.pi:
        return (f'note: joint values are radians unless --deg; {max(given, key=abs):g} rad is more than a turn '
                '(degrees? add --deg)')
    return None


def main(argv=None):
    args = build_parser().parse_args(argv)
    for name, default in OPTIONS.items():
        if not hasattr(args, name):
            setattr(args, name, default)
    try:
        hint = degrees_hint(args)
    except ValueError:
        hint = None
    if hint:
        print(hint, file=sys.stderr)
    if not args.paper and args.method is None:
        build_parser().error('give a method (cubic, quintic, lspb, via-lspb, quintic-via, arc) or --paper')
    if not (np.isfinite(args.dt) and args.dt > 0):
        build_parser().error('--dt must be a positive number of seconds')
    args.out.mkdir(parents=True, exist_ok=True)
    try:
        if args.paper:
            lines, files = run_paper(args.out, args.dt)
            print('The paper, reproduced (formulas win where its printed numbers differ):')
            print('\n'.join('  ' + line for line in lines))
        elif args.method == 'workspace':
            arm, tool, files = save_workspace(args.urdf, args.samples, args.out)
            radial = np.linalg.norm(tool, axis=1)
            print(f'{arm}: tool within {radial.max():.3f} m of base_link; wrist-centre reach shell '
                  f'{arm.reach[0]:.3f}-{arm.reach[1]:.3f} m about the shoulder')
        elif args.method == 'arc':
            arc = geometry.Arc.through(args.p1, args.p2, args.p3)
            path = geometry.CartesianPath.timed(arc, args.duration, args.profile)
            t = _sample_grid(path.duration, args.dt)
            p, v, a = path.sample(t)
            files = save_arc(arc, args.n, args.out)
            files.append(write_csv(args.out / 'arc_timed.csv', t, p, v, a))
            print(f'arc: centre {np.round(arc.center, 6).tolist()}, radius {arc.radius:.6g}, '
                  f'sweep {np.degrees(arc.sweep):.2f} deg, length {arc.length:.6g}; '
                  f'polyline error with {args.n} insertion points {arc.chord_error(args.n + 2):.3g}')
        else:
            traj = plan_from_args(args)
            unit = 'deg' if args.deg else 'rad'
            files = save_profile(traj, args.out, args.method, f'{args.method}', unit, args.dt)
            q, qd, qdd = traj.sample(_sample_grid(traj.duration, args.dt))
            print(f'{args.method}: {traj.duration:.6g} s, {q.shape[1]} joint(s), peak |velocity| '
                  f'{np.abs(qd).max():.6g} {unit}/s, peak |acceleration| {np.abs(qdd).max():.6g} {unit}/s^2')
    except ValueError as exc:
        print(f'picking-plan: {exc}', file=sys.stderr)
        return 2
    print('wrote:')
    for f in files:
        print(f'  {f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
