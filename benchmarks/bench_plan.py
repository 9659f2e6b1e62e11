"""The Table 1 pick cycle: planning time in process, tracking on the simulator, jerk-limited cycle time."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from harness import fmt_time, median, p99, time_calls

from picking_core import trajectory
from picking_core.analysis import corner_path, pick_corners
from picking_core.kinematics import ArmModel, pose_matrix
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import Planner, PlannerSettings
from picking_description import default_urdf

ROOT = Path(__file__).resolve().parents[1]
#: Row 7: how far from P1 and P3, and below P4, the joint moves meet the lines (PickSettings.blend_radius,
#: box_blend_radius: config/pick_cycle.yaml's), m.
BLEND_RADIUS, BOX_BLEND_RADIUS = 0.02, 0.10
#: s: the shipped pick cycle's release_lead (config/pick_cycle.yaml).
RELEASE_LEAD = 0.2
APPLE = pose_matrix([0.70, 0.15, 0.65], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)])   # config/pick_cycle.yaml


def _arm():
    return ArmModel.from_urdf(default_urdf())


def _start(settings):
    home = np.asarray(settings.home_positions, float)
    return home, np.zeros_like(home), np.zeros_like(home)


def planning_time(repeats=150):
    """Row 2: plan the cycle (IK of every knot and line sample, timing, checks) and sample it at 100 Hz."""
    arm = _arm()
    planner = Planner(arm, PlannerSettings(speed_scale=1.0))
    settings = PickSettings().validate(arm)
    start = _start(settings)

    def plan_and_sample():
        plan = PickCycle(planner, settings).plan(start, APPLE)
        plan.samples(0.01)

    times = time_calls({'plan': plan_and_sample}, repeats=repeats, warmup=10)['plan']
    m = median(times)
    row = ['2', 'plan the Table 1 cycle in process (IK + sampling at 100 Hz)', f'{fmt_time(m)} (p99 {fmt_time(p99(times))})',
           f'{len(times)} runs', 'median ≤ 2 ms', 'met' if m <= 2e-3 else 'missed']
    print('  ' + ' | '.join(row), flush=True)
    return [row]


def _peak_jerk_ratio(arm, plan):
    t = np.linspace(0.0, plan.duration, int(plan.duration / 5e-4))
    jerk = np.abs(plan.trajectory.jerk(t))[:, :arm.dof]
    return float(np.max(jerk / arm.max_jerk))


def _accel_steps(arm, plan):
    """Largest step of any joint's acceleration inside the plan, rad/s^2 (an unbounded jerk if > 0)."""
    eps = 1e-7
    b = plan.trajectory.breaks[1:-1]
    if b.size == 0:
        return 0.0
    before = plan.trajectory.sample(b - eps)[2][:, :arm.dof]
    after = plan.trajectory.sample(b + eps)[2][:, :arm.dof]
    return float(np.abs(after - before).max())


def _rest_floor(planner, plan, label):
    """``(duration, floor, joints)`` of the segment ``label``: the floor is the quickest move, within the
    limits ``planner`` plans with, of the joints at rest at both its ends (Ruckig, each joint on its own)."""
    arm = planner.arm
    seg = next(s for s in plan.segments if s.label == label)
    (q0, v0, _), (q1, v1, _) = (plan.trajectory.state_at(t) for t in (seg.start, seg.start + seg.duration))
    limits = (planner._vmax, planner._amax, planner._jmax)
    floor, joints = 0.0, []
    for j in range(arm.dof):
        if max(abs(v0[j]), abs(v1[j])) < 1e-6 and abs(q1[j] - q0[j]) > 1e-9:
            t = trajectory.time_optimal([q0[j]], [q1[j]], *(x[j] for x in limits)).duration
            if t > floor:
                floor, joints = t, [arm.joint_names[j]]
    return seg.duration, floor, joints


def _corner_passes(arm, sharp, rounded):
    """``(corner, distance)``: how close the tool of ``rounded`` passes each corner of ``sharp`` (where its
    lines begin or end: P1, P3, P4 on the way in and out), in the joint move that rounds it, m."""
    return [(name, float(np.linalg.norm(corner_path(arm, rounded, name) - point, axis=1).min()))
            for name, point, _ in pick_corners(arm, sharp)]


def jerk_limited_cycle():
    """Row 7: the cycle within velocity, acceleration and jerk limits, optimal segments against fixed-time ones."""
    arm = _arm()
    start = _start(PickSettings())
    jerk_limited = Planner(arm, PlannerSettings(speed_scale=1.0, method='optimal', path_method='optimal',
                                                limit_jerk=True, cartesian_profile='optimal'))
    optimal, sharp, stopping = (
        PickCycle(jerk_limited, PickSettings(approach_method='optimal', transfer_method='optimal', blend=blend,
                                             blend_radius=radius, box_blend_radius=box).validate(arm)).plan(
            start, APPLE)
        for blend, radius, box in ((True, BLEND_RADIUS, BOX_BLEND_RADIUS), (True, 0.0, 0.0), (False, 0.0, 0.0)))
    led = PickCycle(jerk_limited, PickSettings(approach_method='optimal', transfer_method='optimal', blend=True,
                                               blend_radius=BLEND_RADIUS, box_blend_radius=BOX_BLEND_RADIUS,
                                               release_lead=RELEASE_LEAD).validate(arm)).plan(start, APPLE)
    # The paper's way (Sec. 3.2 D): every section a fixed 2 s, cubic with parabolic blends (LSPB), lines
    # and dwells as in our cycle.
    fixed = PickCycle(Planner(arm, PlannerSettings(speed_scale=1.0, duration=2.0)),
                      PickSettings().validate(arm)).plan(start, APPLE)
    # Our paper-profile cycle at full speed (LSPB segments): fast, but its acceleration steps.
    paper_fast = PickCycle(Planner(arm, PlannerSettings(speed_scale=1.0)), PickSettings().validate(arm)).plan(
        start, APPLE)
    segments = ', '.join(f'{s.label.split()[0]} {s.duration:.2f}' for s in optimal.segments)
    # Where the cycle's time goes: the turns to the box and back start and end with the waist at rest
    # (the lines at P3, P4 and out of the box are vertical), so neither can be quicker than that joint's
    # own fastest rest-to-rest move within the same limits.
    floors = []
    for label, name in (('P4 above the box', 'transfer'), ('P0 back home', 'return')):
        took, floor, joints = _rest_floor(jerk_limited, optimal, label)
        floors.append(f'{name} {took:.3f} s, where {"/".join(joints) or "no joint"} (at rest at both ends) '
                      f'needs ≥ {floor:.3f} s')
    lines = sum(s.duration for s in optimal.segments if s.label.startswith(('P2', 'P3', 'P5', 'P4 out')))
    dwells = sum(s.duration for s in optimal.segments if s.label in ('grasp', 'release'))
    passes = ', '.join(f'{corner} {1e3 * d:.1f} mm' for corner, d in _corner_passes(arm, sharp, optimal))
    rows = [['7', 'Table 1 cycle within v, a and jerk limits: optimal (Ruckig) segments, P1, P3, P4 passed at speed, '
             f'corners rounded (blend_radius {100 * BLEND_RADIUS:g} cm; box_blend_radius {100 * BOX_BLEND_RADIUS:g} cm: '
             'the apple lowered into the box during the swing)',
             f'{optimal.duration:.2f} s', f'peak jerk {_peak_jerk_ratio(arm, optimal):.2f} of the limit; {segments}; '
             + '; '.join(floors) + f'; four lines {lines:.2f} s, two dwells {dwells:.2f} s; the tool passes the '
             f'corners at {passes}', '≤ 5 s', 'met' if optimal.duration <= 5.0 else 'missed'],
            ['7', f'the same, the fingers opening on the line into the box (release_lead {RELEASE_LEAD:g} s, as '
                  'shipped)', f'{led.duration:.2f} s', f'peak jerk {_peak_jerk_ratio(arm, led):.2f} of the limit; the '
                  f"release's dwell at P5 {next(x.duration for x in led.segments if x.label == 'release'):.2f} s", '—',
             f'saves {optimal.duration - led.duration:.2f} s'],
            ['7', 'the same, through the corners (blend radii 0: the lines end at P1, P3, P4)',
             f'{sharp.duration:.2f} s', f'peak jerk {_peak_jerk_ratio(arm, sharp):.2f} of the limit', '—',
             f'rounding saves {sharp.duration - optimal.duration:.2f} s'],
            ['7', 'the same, stopping at every knot point (blend: false)', f'{stopping.duration:.2f} s',
             f'peak jerk {_peak_jerk_ratio(arm, stopping):.2f} of the limit', '—',
             f'passing at speed saves {stopping.duration - sharp.duration:.2f} s'],
            ['7', "the paper's fixed-time segments (2 s each, LSPB)", f'{fixed.duration:.2f} s',
             f'acceleration steps up to {_accel_steps(arm, fixed):.1f} rad/s² (unbounded jerk)', '—',
             f'optimal {fixed.duration / optimal.duration:.1f}x faster'],
            ['7', 'our LSPB cycle at full speed (v, a limits only)', f'{paper_fast.duration:.2f} s',
             f'acceleration steps up to {_accel_steps(arm, paper_fast):.1f} rad/s² (unbounded jerk)', '—', '—']]
    for row in rows:
        print('  ' + ' | '.join(row), flush=True)
    return rows


def tracking(quick=False):
    """Row 5: run the demo on the simulator and read its report (measured joint_states against the plan)."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [str(Path(sys.executable).parent / 'picking-demo'), '--out', out, '--quick']
        done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy(), timeout=600)
        if done.returncode != 0:
            print(done.stdout[-2000:], done.stderr[-2000:])
            return [['5', 'servo tracking through the pick cycle', 'demo failed', f'exit {done.returncode}',
                     'max ≤ 0.2°, final ≤ 0.01°', 'missed']]
        report = json.loads((Path(out) / 'report.json').read_text())
    joints = report['joints']
    arm_idx = [i for i, n in enumerate(joints) if n != 'gripper_joint']
    worst = np.degrees(max(report['max_tracking_error'][i] for i in arm_idx))
    final = np.degrees(max(abs(report['final_error'][i]) for i in arm_idx))
    row = ['5', 'servo tracking through the pick cycle (demo on the simulator)',
           f'max {worst:.3f}°, final {final:.4f}°', f'cycle {report["cycle_time_s"]:.2f} s; arm joints',
           'max ≤ 0.2°, final ≤ 0.01°', 'met' if worst <= 0.2 and final <= 0.01 else 'missed']
    print('  ' + ' | '.join(row), flush=True)
    return [row]
