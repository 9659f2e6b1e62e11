"""The demo's report: what a motion engineer wants to see after a pick cycle."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from picking_common.status import stamp_key, status_values
from picking_core.analysis import (
    REFERENCE_BOUND,
    cartesian_deviation,
    corner_path,
    parse_segments,
    peak_jerk,
    pick_corners,
    reference_deviation,
    tracking_error,
)
from picking_core.kinematics import ArmModel, pose_matrix
from picking_core.pick_cycle import PickCycle, PickSettings
from picking_core.planning import Planner, PlannerSettings
from picking_core.trajectory import through_waypoints
from picking_description import DEFAULT_ARM, urdf_path


def log(msg):
    print(f'[demo {time.strftime("%H:%M:%S")}] {msg}', flush=True)


def stop_stack(stack):
    """Stop a scenario's ``stack`` by its processes' ids, each exit code logged; returns them by node."""
    codes = stack.stop()
    for name, code in codes.items():
        log(f'stopped {name}: exit code {code}')
    return codes


def run_tool(argv, timeout):
    """Run a command-line tool, each line it prints logged as it comes (a long harvest shows its progress);
    a CompletedProcess with what it printed. The tool is killed after ``timeout`` s."""
    import subprocess
    import threading
    proc = subprocess.Popen([str(a) for a in argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=os.environ.copy())
    err = []
    reader = threading.Thread(target=lambda: err.extend(proc.stderr), daemon=True)
    reader.start()
    killer = threading.Timer(timeout, proc.kill)
    killer.start()
    out = []
    try:
        for line in proc.stdout:
            out.append(line)
            log('  ' + line.rstrip('\n'))
        proc.wait()
    finally:
        killer.cancel()
    reader.join(timeout=5.0)
    return subprocess.CompletedProcess(proc.args, proc.returncode, ''.join(out), ''.join(err))


def load_demo_settings(config, arm=None):
    """The apple pose and the demo's own values from pick_cycle.yaml (``picking_demo`` section), and the
    planner's values there with those of ``arm``'s own file (``arms/<arm>.yaml``) on top."""
    from .shipped import arm_files
    data = yaml.safe_load((config / 'pick_cycle.yaml').read_text()) or {}
    demo = (data.get('picking_demo') or {}).get('ros__parameters') or {}
    planner = {}
    for part in [data] + [yaml.safe_load((config / f).read_text()) or {} for f in arm_files(arm)]:
        planner.update(next((v.get('ros__parameters', {}) for k, v in part.items() if k.endswith('picking_planner')),
                            {}))
    return demo, planner


def _stamp(s):
    return s.sec + s.nanosec * 1e-9


def planned_arrays(msg, t_received):
    """Names, absolute times and q, qd, qdd of a JointTrajectory."""
    t0 = _stamp(msg.header.stamp) or t_received
    t = np.array([t0 + p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points])
    q = np.array([p.positions for p in msg.points])
    qd = np.array([p.velocities for p in msg.points])
    qdd = np.array([p.accelerations for p in msg.points])
    return list(msg.joint_names), t, q, qd, qdd


def measured_arrays(messages, names):
    rows = [(_stamp(m.header.stamp), [m.position[list(m.name).index(n)] for n in names]) for _, m in messages]
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])


def _since(s, origin):
    """Seconds from stamp ``origin`` to stamp ``s``, to the nanosecond (as a float of the epoch, a
    stamp is good to a quarter of a microsecond only: too coarse for a plan's acceleration steps)."""
    return (s.sec - origin.sec) + (s.nanosec - origin.nanosec) * 1e-9


def commanded_arrays(messages, names, origin):
    """Times since stamp ``origin`` and q, qd, qdd of ``joint_commands`` (the acceleration rides in
    ``effort``) for ``names``."""
    t, q, qd, qdd = [], [], [], []
    for _, m in messages:
        cols = [list(m.name).index(n) for n in names]
        t.append(_since(m.header.stamp, origin))
        for out, field in ((q, m.position), (qd, m.velocity), (qdd, m.effort)):
            out.append([field[c] for c in cols])
    return np.array(t), np.array(q), np.array(qd), np.array(qdd)


def _table(header, rows):
    """A Markdown table; a pipe inside a cell (``peak |v|``) is escaped, so that every row keeps its cells."""
    def cell(c):
        return str(c).replace('|', '\\|')
    out = ['| ' + ' | '.join(cell(h) for h in header) + ' |', '| ' + ' | '.join('---' for _ in header) + ' |']
    out += ['| ' + ' | '.join(cell(c) for c in r) + ' |' for r in rows]
    return '\n'.join(out)


#: compare_methods' labels of the jerk-limited cycle through its corners and with them rounded.
THROUGH_CORNERS = 'optimal, jerk-limited, P1, P3, P4 passed at speed'
#: m, the blend radii of the rounded cycle (at the apple, over the box).
ROUND_RADIUS, BOX_ROUND_RADIUS = 0.02, 0.10
ROUNDED = (f'the same, corners rounded (blend_radius {100 * ROUND_RADIUS:g} cm, box_blend_radius '
           f'{100 * BOX_ROUND_RADIUS:g} cm)')


def compare_methods(arm, planner_params, apple_T):
    """The same cycle with cubic, quintic and LSPB segments, and jerk-limited (optimal, blended, with and
    without rounded corners): ``(rows, plans)``, a row (label, cycle time, peak |qdd|, largest jerk) and
    the plan of each, by label."""
    settings = PlannerSettings(**{k: v for k, v in planner_params.items()
                                  if k in PlannerSettings.__dataclass_fields__})
    pick = PickSettings(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in planner_params.items()
                           if k in PickSettings.__dataclass_fields__}).validate(arm)
    home = np.asarray(pick.home_positions, float)
    z = np.zeros(arm.dof)
    rows, plans = [], {}
    jerk_limited = dict(method='optimal', path_method='optimal', limit_jerk=True, cartesian_profile='optimal')
    paper = dict(limit_jerk=False, cartesian_profile='quintic')
    stops = dict(blend=False, blend_radius=0.0, box_blend_radius=0.0)
    for label, changes, pick_changes in (
            ('cubic (transfer quintic_via)', dict(method='cubic', **paper),
             dict(approach_method='cubic', transfer_method='quintic_via', **stops)),
            ('quintic (transfer quintic_via)', dict(method='quintic', **paper),
             dict(approach_method='quintic', transfer_method='quintic_via', **stops)),
            ('lspb (transfer via_lspb)', dict(method='lspb', **paper),
             dict(approach_method='lspb', transfer_method='via_lspb', **stops)),
            (THROUGH_CORNERS, jerk_limited,
             dict(approach_method='optimal', transfer_method='optimal', blend=True, blend_radius=0.0,
                  box_blend_radius=0.0)),
            (ROUNDED, jerk_limited,
             dict(approach_method='optimal', transfer_method='optimal', blend=True, blend_radius=ROUND_RADIUS,
                  box_blend_radius=BOX_ROUND_RADIUS))):
        planner = Planner(arm, PlannerSettings(**{**settings.__dict__, **changes}))
        plan = PickCycle(planner, PickSettings(**{**pick.__dict__, **pick_changes}).validate(arm)).plan(
            (home, z, z), apple_T)
        t = np.arange(0.0, plan.duration, 0.001)
        _, _, qdd = plan.trajectory.sample(t)
        rows.append((label, f'{plan.duration:.2f}', f'{np.abs(qdd[:, :arm.dof]).max():.2f}',
                     f'{peak_jerk(t, qdd[:, :arm.dof]).max():.0f}'))
        log(f'  {label}: cycle {plan.duration:.2f} s')
        plans[label] = plan
    return rows, plans


@dataclass
class PickRun:
    """The pick as planned and as run: the plan's samples (absolute times), the measured joints, the tracking error
    at the measurement stamps, and the cycle's segments with their start times."""

    msg: object
    names: list
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    t_meas: np.ndarray
    q_meas: np.ndarray
    err: np.ndarray
    final: np.ndarray
    segments: list
    starts: np.ndarray

    @classmethod
    def from_recording(cls, rec, events):
        """The pick's plan as the controller ran it (a plan that reached it too late was planned again)."""
        trajectories = rec.messages('planned_trajectory')
        ran = {status_values(m).get('trajectory') for _, m in rec.messages('controller_status')
               if m.message == 'trajectory accepted'}
        t_recv, msg = next((x for x in trajectories if stamp_key(x[1].header.stamp) in ran), trajectories[0])
        names, t, q, qd, qdd = planned_arrays(msg, t_recv)
        t_meas, q_meas = measured_arrays(rec.messages('joint_states'), names)
        # Final error: the arm at rest, 0.3 s after the plan's end (or the last sample before the next goal).
        after = np.flatnonzero(t_meas >= t[-1] + 0.3)
        final = np.abs(q_meas[after[0] if after.size else -1] - q[-1])
        segments = parse_segments(events['plan']['segments'])
        starts = np.concatenate(([0.0], np.cumsum([seg[2] for seg in segments])))[:-1] + t[0]
        return cls(msg, names, t, q, qd, qdd, t_meas, q_meas, tracking_error(t, q, t_meas, q_meas), final, segments,
                   starts)

    @property
    def window(self):
        """The measurements within the plan's time."""
        return ~np.isnan(self.err[:, 0])


def analyse_and_report(rec, events, config, out, quick=False, arm_name=None):
    """Write report.md, report.json, plots and demo.mcap for the run on ``arm_name`` (a shipped arm; default:
    the picking arm); log a summary; True if all checks pass."""
    arm = ArmModel.from_urdf(urdf_path(arm_name or DEFAULT_ARM))
    demo, planner_params = load_demo_settings(config, arm_name)
    planner_yaml = yaml.safe_load((config / 'planner.yaml').read_text())
    params = {**next(iter(planner_yaml.values()))['ros__parameters'], **planner_params}
    run = PickRun.from_recording(rec, events)
    peaks, checks, deviation = limit_checks(arm, run, rec)
    lines = pick_lines(arm, run, events, demo, params, peaks, deviation, checks)
    apple_T = pose_matrix(demo['apple_position'], Rotation.from_euler('xyz', demo['apple_rpy']).as_quat())
    compared = {}
    if not quick:
        log('planning the same cycle with cubic, quintic, LSPB and jerk-limited segments')
        rows, compared = compare_methods(arm, params, apple_T)
        lines += comparison_lines(rows)
    if 'arc' in events:
        lines += arc_section(rec, events['arc'], arm, run.names)
    log('plotting and writing the report')
    files = pick_plots(arm, run, rec, events, planner_params, apple_T, compared, out)
    if 'harvest' in events:
        section, harvest_plot, harvest_checks = harvest_section(rec, events['harvest'], arm, out)
        lines += section
        checks.update(harvest_checks)
        files += [harvest_plot] if harvest_plot is not None else []
    if rec.count('/tf'):
        files.append(viewer_picture(rec, out, run.t, run.segments, run.starts))
    mcap_path, n_msgs = rec.write_mcap(out / 'demo.mcap')
    files.append(mcap_path)
    decoded = _check_mcap(mcap_path)
    checks['MCAP decodes with mcap_ros2'] = decoded == n_msgs
    lines += ['', '## Checks', '', *[f'- {k}: {"yes" if v else "NO"}' for k, v in checks.items()]]
    lines += ['', '## Files', ''] + [f'- `{f}`' for f in files] + [
        '', f'`demo.mcap`: {n_msgs} messages on {len(rec.types)} topics, all decoded again with mcap_ros2 '
        f'({decoded}); open it in Foxglove or with `ros2 bag info`.']
    (out / 'report.md').write_text('\n'.join(lines) + '\n')
    (out / 'report.json').write_text(json.dumps({
        'cycle_time_s': float(run.t[-1] - run.t[0]), 'segments': run.segments, 'joints': run.names,
        **{k: v.tolist() for k, v in peaks.items()},
        'reference_deviation': None if deviation is None else [d.tolist() for d in deviation[:3]],
        'max_tracking_error': np.nanmax(np.abs(run.err), axis=0).tolist(), 'final_error': run.final.tolist(),
        'cartesian': cartesian_rows(arm, run), 'checks': checks, 'files': [str(f) for f in files]}, indent=2))
    log(f'pick cycle: {run.t[-1] - run.t[0]:.2f} s planned; goal reached {events["cycle_wall"]:.2f} s after it was '
        f'sent; largest tracking error {np.degrees(np.nanmax(np.abs(run.err[:, :arm.dof]))):.3f}°')
    log_checks('the pick cycle', checks)
    return all(checks.values())


def limit_checks(arm, run, rec):
    """The plan's peaks against the limits (sampled every millisecond as the controller runs it: quintics between
    the points, acceleration steps kept) and the controller's reference against the plan: ``(peaks, checks,
    deviation)``."""
    lower, upper, vmax, amax = arm.all_limits
    idx = [list(arm.all_joint_names).index(n) for n in run.names]
    msg = run.msg
    plan = through_waypoints([_since(p.time_from_start, msg.points[0].time_from_start) for p in msg.points],
                             run.q, run.qd, run.qdd)
    t_ms = np.arange(0.0, plan.duration, 1e-3)
    _, qd_ms, qdd_ms = plan.sample(t_ms)
    peaks = {'peak_velocity': np.maximum(np.abs(run.qd).max(axis=0), np.abs(qd_ms).max(axis=0)),
             'peak_acceleration': np.maximum(np.abs(run.qdd).max(axis=0), np.abs(qdd_ms).max(axis=0)),
             'largest_jerk': peak_jerk(t_ms, qdd_ms)}
    # What the controller commanded against that plan: from its start or, when it came late and a
    # catch-up lead-in replaced its beginning, from where it took over; a stalled loop delays it on purpose.
    t_cmd, *cmd = commanded_arrays(rec.messages('joint_commands'), run.names, msg.header.stamp)
    controller = [(m.message, status_values(m)) for _, m in rec.messages('controller_status')]
    caught_up = next((float(v.get('caught_up', 0.0)) for text, v in controller if text == 'trajectory accepted'
                      and v.get('trajectory') == stamp_key(msg.header.stamp)), 0.0)
    deviation = reference_deviation(plan, _stamp(msg.points[0].time_from_start) + caught_up, t_cmd, *cmd)
    limited = [text for text, _ in controller if 'command limited' in text]
    stalled = [text for text, _ in controller if 'control loop stalled' in text]
    q = run.q
    checks = {'velocity within limits': bool(np.all(peaks['peak_velocity'] <= vmax[idx] * (1 + 1e-6))),
              'acceleration within limits': bool(np.all(peaks['peak_acceleration'] <= amax[idx] * (1 + 1e-6))),
              'positions within limits': bool(np.all((q >= lower[idx] - 1e-9) & (q <= upper[idx] + 1e-9))),
              'the controller commanded the plan (no "command limited")': not limited,
              'commanded acceleration within limits': bool(np.all(np.abs(cmd[2]) <= amax[idx] * (1 + 1e-6)))}
    if not stalled:
        checks['the commanded reference within the bound of the plan'] = deviation is not None and all(
            d.max() <= b for d, b in zip(deviation, REFERENCE_BOUND))
    notes = {'duration': plan.duration, 'caught_up': caught_up, 'limited': limited, 'stalled': stalled}
    return peaks, checks, None if deviation is None else (*deviation, notes)


def cartesian_rows(arm, run):
    """For each line and arc of the cycle: (label, kind, length mm, plan deviation mm, measured deviation mm), the
    requested line or arc from the plan's own tool points, the tool measured by FK of joint_states."""
    rows = []
    for (label, method, dur), start in zip(run.segments, run.starts):
        if method not in ('line', 'arc'):
            continue
        seg_plan = (run.t >= start - 1e-9) & (run.t <= start + dur + 1e-9)
        seg_meas = (run.t_meas >= start) & (run.t_meas <= start + dur)
        tool_plan = arm.fk(run.q[seg_plan, :arm.dof])[:, :3, 3]
        a, mid, b = tool_plan[0], tool_plan[len(tool_plan) // 2], tool_plan[-1]
        dev_plan = cartesian_deviation(method, a, mid, b, tool_plan)
        dev_meas = cartesian_deviation(method, a, mid, b, arm.fk(run.q_meas[seg_meas, :arm.dof])[:, :3, 3]) \
            if seg_meas.any() else float('nan')
        rows.append((label, method, f'{np.linalg.norm(b - a) * 1e3:.1f}', f'{dev_plan * 1e3:.3f}',
                     f'{dev_meas * 1e3:.3f}'))
    return rows


def pick_lines(arm, run, events, demo, params, peaks, deviation, checks):
    """The report's first sections: the cycle, its segments, the joints against their limits, the reference, the
    Cartesian segments, the gripper."""
    _, _, vmax, amax = arm.all_limits
    idx = [list(arm.all_joint_names).index(n) for n in run.names]
    n_arm, err = arm.dof, run.err
    pv, pa, jerk = peaks['peak_velocity'], peaks['peak_acceleration'], peaks['largest_jerk']

    def tracking(i):
        worst = np.nanmax(np.abs(err[:, i]))
        return f'{worst:.5f} ({np.degrees(worst):.3f}°)' if i < n_arm else f'{worst * 1e3:.2f} mm'
    lines = ['# Pick-and-place demo (Table 1 on the simulator)', '',
             f'- cycle time (plan): **{run.t[-1] - run.t[0]:.2f} s**; goal reached {events["cycle_wall"]:.2f} s '
             'after pick_target was published (planning, transport and settling included)',
             f'- apple at {demo["apple_position"]} m, box drop point at {params.get("box_position")} m, '
             f'speed_scale {params.get("speed_scale")}',
             f'- planning time in the planner node: {float(events["plan"].get("planning_ms", "nan")):.1f} ms', '',
             '## Segments', '', _table(['segment', 'method', 'duration [s]'],
                                       [(lb, m, f'{d:.3f}') for lb, m, d in run.segments]), '',
             '## Joints: peaks against the limits, tracking', '',
             _table(['joint', 'peak |v|', 'v limit', 'peak |a|', 'a limit', 'largest jerk', 'max tracking error',
                     'final error'],
                    [(n, f'{pv[i]:.3f}', f'{vmax[idx[i]]:.3g}', f'{pa[i]:.3f}', f'{amax[idx[i]]:.3g}',
                      f'{jerk[i]:.1f}', tracking(i), f'{run.final[i]:.2e}') for i, n in enumerate(run.names)]),
             '', 'Units: rad, rad/s, rad/s², rad/s³ (the gripper: m, m/s, m/s², m/s³). Tracking error: measured '
             '`joint_states` minus the planned trajectory at the measurement stamp.', '']
    if deviation is not None:
        dq, dqd, dqdd, ticks, notes = deviation
        lines += [f'Largest deviation of the commanded reference (`joint_commands`, {ticks} ticks recorded) '
                  f'from the plan over its {notes["duration"]:.2f} s: {dq.max():.1e} rad, {dqd.max():.1e} rad/s, '
                  f'{dqdd.max():.1e} rad/s² (bound: {REFERENCE_BOUND[0]:g} rad, {REFERENCE_BOUND[1]:g} rad/s, '
                  f'{REFERENCE_BOUND[2]:g} rad/s², docs/controller.md)'
                  + (f', after a {notes["caught_up"]:.3f} s catch-up (the plan reached the controller late)'
                     if notes['caught_up'] else '')
                  + (f'; the controller said: {notes["limited"][0]}' if notes['limited'] else '')
                  + (f'; not checked: {notes["stalled"][0]}' if notes['stalled'] else '') + '.', '']
    lines += ['## Cartesian segments: the tool against the requested line or arc', '',
              _table(['segment', 'kind', 'length [mm]', 'plan deviation [mm]', 'measured deviation [mm]'],
                     cartesian_rows(arm, run))]
    grasp = events['plan']
    if 'grasp_start' in grasp:
        lines += ['', f'Gripper: closes from {float(grasp["grasp_start"]):.2f} s to {float(grasp["grasp_end"]):.2f} s, '
                      f'opens from {float(grasp["release_start"]):.2f} s to {float(grasp["release_end"]):.2f} s '
                      '(`gripper_joint` in joint_states).']
    return lines


def comparison_lines(rows):
    """The report's section comparing the cycle planned with each method."""
    return ['', '## The same cycle with cubic, quintic, LSPB and jerk-limited segments (planned in process)', '',
            _table(['method', 'cycle time [s]', 'peak |qdd| [rad/s²]', 'largest jerk [rad/s³]'], rows),
            '', 'Cubic segments start and stop with a step in acceleration (an infinite jerk, here the '
            'acceleration change within one 1 ms sample); LSPB blends too; quintics keep acceleration '
            'continuous. The paper\'s claim that parabolic transitions move smoothly is about velocity '
            'continuity: measured here, LSPB is the fastest of them for the same limits but not the smoothest. '
            'The jerk-limited cycle (Ruckig\'s time-optimal segments within the jerk limits of '
            '`picking_description/urdf/picking_arm_joint_limits.yaml`, `blend: true`) keeps every jerk limit at a '
            'fraction of a second more; rounding its corners at P1 and P3 (`blend_radius`) and lowering the apple '
            'into the box during the swing (`box_blend_radius`) takes about half a second off (`corners.png`: the '
            'tool at each corner, side on).']


def pick_plots(arm, run, rec, events, planner_params, apple_T, compared, out):
    """joints.png, tracking_error.png, tool_path.png and (with the comparison) corners.png; their paths."""
    from .plots import plot_corners, plot_path_3d, plot_profiles
    n_arm, t, q, window = arm.dof, run.t, run.q, run.window
    files = [plot_profiles(out / 'joints.png', t - t[0], q[:, :n_arm], run.qd[:, :n_arm], run.qdd[:, :n_arm],
                           'Pick cycle: planned joint position, velocity, acceleration (Figs. 9-11, 14)', 'rad',
                           labels=run.names[:n_arm], marks=run.starts - t[0], mark_labels=[s[0] for s in run.segments],
                           extra=('gripper opening', q[:, n_arm], 'm') if q.shape[1] > n_arm else None),
             _plot_error(out / 'tracking_error.png', run.t_meas[window] - t[0], run.err[window], run.names,
                         arm.joint_names)]
    key = PickCycle(Planner(arm), PickSettings(**{k: (tuple(v) if isinstance(v, list) else v)
                                                 for k, v in planner_params.items()
                                                 if k in PickSettings.__dataclass_fields__})).key_poses(apple_T)
    home = np.asarray(planner_params.get('home_positions'), float)
    marks = {'P0': arm.fk(home)[:3, 3], **{k: v[:3, 3] for k, v in key.items()}}
    curves = {'planned': arm.fk(q[:, :n_arm])[:, :3, 3], 'measured': arm.fk(run.q_meas[window][:, :n_arm])[:, :3, 3]}
    if 'arc' in events:
        trajectories = rec.messages('planned_trajectory')
        received, msg = trajectories[events['arc']['trajectory_index']]
        curves['scenario 2: the Sec. 3.1 arc (planned)'] = arm.fk(planned_arrays(msg, received)[2][:, :n_arm])[:, :3, 3]
    files.append(plot_path_3d(out / 'tool_path.png', curves, None, 'Tool path of the pick cycle (P0-P5 as in the '
                              'README)', marks, unit='m'))
    if compared:
        corners = pick_corners(arm, compared[THROUGH_CORNERS])
        tracks = {label: {name: corner_path(arm, compared[k], name) for name, _, _ in corners}
                  for label, k in (('through the corners', THROUGH_CORNERS), ('rounded', ROUNDED))}
        files.append(plot_corners(out / 'corners.png', corners, tracks,
                                  'Jerk-limited cycle: the tool at its corners, through them and rounded',
                                  caption='Each panel: the tool within 5 cm of a corner of the cycle, side on. "Through '
                                          'the corners": blend, the joint moves meet the lines at P1, P3 and P4 at '
                                          'speed; "rounded": they meet the lines blend_radius before (box_blend_radius '
                                          'at P4). "P4 in" and "P4 out": the line into the box and the line out of it.'))
    return files


def log_checks(what, checks):
    """One line for a scenario's checks: how many hold, and each that does not."""
    failed = [k for k, v in checks.items() if not v]
    log(f'{what}: {len(checks) - len(failed)} of {len(checks)} checks hold'
        + (f'; NOT: {"; ".join(failed)}' if failed else ''))


def harvest_statuses(rec, key):
    """What planner_status said of harvest ``key``: ``{'picked': [(apple, at s)] in picking order,
    'missed' and 'skipped': [(apple, reason)], 'places': {apple: (x, y, z) m}, 'accepted': values, 'final': values}``."""
    out = {'picked': [], 'missed': [], 'skipped': [], 'places': {}, 'accepted': {}, 'final': {}}
    for _, m in rec.messages('planner_status'):
        v = status_values(m)
        if v.get('goal') != key:
            continue
        if 'apple' in v and 'x' in v:
            out['places'][int(v['apple'])] = tuple(float(v[k]) for k in 'xyz')
        if v.get('apple_state') == 'picked':
            out['picked'].append((int(v['apple']), float(v['at'])))
        elif v.get('apple_state') in ('skipped', 'missed'):
            out[v['apple_state']].append((int(v['apple']), m.message.split(': ', 2)[-1]))
        elif v.get('state') == 'accepted':
            out['accepted'] = v
        elif v.get('state') in ('succeeded', 'aborted', 'superseded', 'canceled', 'refused'):
            out['final'] = v
    return out


#: m: the farthest an apple the planner harvested (from the camera) may be from the tree's apple it is taken for.
MATCH = 0.03


def on_the_tree(said, tree):
    """``said`` (:func:`harvest_statuses`) with the planner's apple indices turned into those of the ``tree``'s
    apples (4x4 poses) they are, matched by place within MATCH (an apple whose place was not said keeps its index),
    ``'unmatched'``: the planner's apples that are none of the tree's (a harvest from the camera numbers the
    apples it saw, not the tree's), and ``'astray'``: for each of those, ``(fate, place, distance to the nearest
    of the tree's apples in m, reason)`` (a knocked apple swings away from where it hung)."""
    centres = np.array([T[:3, 3] for T in tree]).reshape(-1, 3)
    index, unmatched, gap = {}, [], {}
    for i, place in said['places'].items():
        d = np.linalg.norm(centres - np.asarray(place), axis=1) if len(centres) else np.array([np.inf])
        if d.min() <= MATCH:
            index[i] = int(d.argmin())
        else:
            unmatched.append(i)
            gap[i] = float(d.min())
    fates = [(i, 'picked', '') for i, _ in said['picked']] + [
        (i, word, why) for word in ('missed', 'skipped') for i, why in said[word]]
    astray = [(word, said['places'][i], gap[i], why) for i, word, why in fates if i in gap]
    return {**said, 'astray': astray, 'picked': [(index.get(i, i), at) for i, at in said['picked'] if i not in unmatched],
            'skipped': [(index.get(i, i), why) for i, why in said['skipped'] if i not in unmatched],
            'missed': [(index.get(i, i), why) for i, why in said['missed'] if i not in unmatched],
            'places': {index[i]: p for i, p in said['places'].items() if i in index}, 'unmatched': unmatched}


def harvest_markers(apples, said, header):
    """visualization_msgs/MarkerArray of a harvested tree: each apple a sphere (red picked, grey
    skipped), its place in the visiting order as text, and the order as a line strip."""
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray
    order = [i for i, _ in said['picked']]
    skipped = {i for i, _ in said['skipped']}
    out = MarkerArray()
    for i, T in enumerate(apples):
        for kind in ('apple', 'order'):
            m = Marker(ns=kind, id=i, action=Marker.ADD)
            m.header.frame_id = header.frame_id or 'base_link'
            m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in T[:3, 3])
            m.pose.orientation.w = 1.0
            if kind == 'apple':
                m.type, m.scale.x, m.scale.y, m.scale.z = Marker.SPHERE, 0.07, 0.07, 0.07
                m.color.r, m.color.g, m.color.b, m.color.a = (0.5, 0.5, 0.5, 0.6) if i in skipped else (0.8, 0.1, 0.1, 1)
            else:
                m.type, m.scale.z, m.text = Marker.TEXT_VIEW_FACING, 0.04, (
                    f'{order.index(i) + 1}' if i in order else 'skipped')
                m.pose.position.z += 0.06
                m.color.r = m.color.g = m.color.b = m.color.a = 1.0
            out.markers.append(m)
    path = Marker(ns='visiting order', id=0, action=Marker.ADD, type=Marker.LINE_STRIP)
    path.header.frame_id = header.frame_id or 'base_link'
    path.pose.orientation.w, path.scale.x = 1.0, 0.005
    path.color.g, path.color.b, path.color.a = 0.6, 1.0, 1.0
    path.points = [Point(x=float(apples[i][0, 3]), y=float(apples[i][1, 3]), z=float(apples[i][2, 3])) for i in order]
    out.markers.append(path)
    return out


def harvest_section(rec, event, arm, out):
    """The report's section on scenario 3 and its plot: ``(lines, plot path, checks)``."""
    from picking_core.harvest import synthetic_tree

    from .plots import plot_harvest
    apples = synthetic_tree(event['apples'], seed=event['seed'])
    said = on_the_tree(harvest_statuses(rec, event['goal']), apples)
    final, accepted = said['final'], said['accepted']
    t_recv, msg = rec.messages('planned_trajectory')[event['trajectory_index']]
    names, t, q, _, _ = planned_arrays(msg, t_recv)
    tool = arm.fk(q[:, :arm.dof])[:, :3, 3]
    order = [i for i, _ in said['picked']]
    ends = [at for _, at in said['picked']]
    rows = [(k + 1, i, f'{np.round(apples[i][:3, 3], 3).tolist()}', f'{at:.2f}',
             f'{at - (ends[k - 1] if k else 0.0):.2f}') for k, (i, at) in enumerate(said['picked'])]
    rows += [(word, i, f'{np.round(apples[i][:3, 3], 3).tolist()}', '', why)
             for word in ('missed', 'skipped') for i, why in said[word]]
    rows += [(word, 'none', f'{np.round(place, 3).tolist()}', '', f'{why + "; " if why else ""}seen '
              f'{100 * gap:.1f} cm from the nearest of the tree\'s apples (one knocked and swinging, or no apple)')
             for word, place, gap, why in said.get('astray', [])]
    unseen = sorted(set(range(len(apples))) - set(order) - {i for word in ('missed', 'skipped') for i, _ in said[word]})
    rows += [('not seen', i, f'{np.round(apples[i][:3, 3], 3).tolist()}', '', 'the fruit map never confirmed it: '
              'hidden from the camera (by the arm, a branch or another apple)') for i in unseen]
    path = plot_harvest(out / 'harvest.png', apples, order, [i for i, _ in said['skipped']], tool,
                        f'Scenario 3: a tree of {len(apples)} apples, its visiting order and the tool path')
    per_apple = float(final.get('harvest_time', 'nan')) / max(int(final.get('picked', 0)), 1)
    how = ('`picking-goal harvest --seen`: the apples the simulator\'s camera sees, as the planner\'s fruit map '
           f'confirmed them, {len(said["places"])} of the {len(apples)}' if event.get('seen') else
           f'`picking-goal harvest --tree {len(apples)} --seed {event["seed"]}`')
    lines = ['', '## Scenario 3: a tree harvested', '',
             f'{len(apples)} apples of the synthetic tree seeded {event["seed"]}, hanging in the simulator ({how}): '
             f'**{final.get("picked")} picked**, {final.get("missed", 0)} missed (the gripper measured holding '
             f'nothing), {final.get("skipped")} skipped, {float(final.get("harvest_time", "nan")):.1f} s planned and run, {per_apple:.2f} s an apple '
             f'(box included): **{float(final.get("apples_per_hour", "nan")):.0f} apples an hour**. Order (estimated '
             f'moves between apples, home and box): {float(accepted.get("order_estimate", "nan")):.2f} s planned '
             f'against {float(accepted.get("given_order_estimate", "nan")):.2f} s in the order given, chosen in '
             f'{float(accepted.get("ordering_ms", "nan")):.0f} ms; the harvest planned in '
             f'{float(accepted.get("planning_ms", "nan")) / 1e3:.2f} s.', '',
             _table(['#', 'apple', 'position [m]', 'in the box at [s]', 'cycle [s] / reason'], rows), '',
             '`harvest.png`: the tree from the front and from above, the visiting order and the tool path; '
             '`demo.mcap` holds the tree as visualization_msgs/MarkerArray on `harvest_markers`.']
    checks = {'the harvest succeeded': final.get('state') == 'succeeded'}
    if event.get('seen'):
        # A grasp where no apple hung must be the planner's own miss, never a pick it claims.
        checks['every apple picked from the camera is one of the tree\'s'] = not any(
            word == 'picked' for word, *_ in said['astray'])
    else:
        checks['every apple picked, missed or skipped with a reason'] = \
            len(order) + len(said['missed']) + len(said['skipped']) == len(apples)
    world_lines, world_checks = world_section(rec, order, len(apples))
    lines += world_lines
    checks.update(world_checks)
    lines += ['', *[f'- {k}: {"yes" if v else "NO"}' for k, v in checks.items()]]
    return lines, path, checks


def world_section(rec, claimed, n):
    """What the simulator counted of the tree's apples ``0 .. n - 1`` (its ``fruit_events``) beside the planner's
    ``claimed`` picks: ``(lines, checks)``. An apple claimed but not in the box is a failure, in red."""
    fates, worst = {}, {}
    for _, m in rec.messages('fruit_events'):
        v = status_values(m)
        i = int(v['apple'])
        fates.setdefault(i, []).append(v['event'])
    in_box = sorted(i for i, e in fates.items() if 'in the box' in e and i < n)
    rows = []
    for word in ('in the box', 'dropped', 'knocked', 'knocked off', 'bruised', 'missed grasp'):
        who = sorted(i for i, e in fates.items() if word in e and i < n)
        worst[word] = who
        rows.append((word, len(who), ', '.join(map(str, who)) or '-'))
    left = sorted(set(range(n)) - {i for i, e in fates.items() if 'detached' in e or 'knocked off' in e})
    rows.append(('left on the tree', len(left), ', '.join(f'{i} (not picked)' for i in left) or '-'))
    wrong = sorted(set(claimed) - set(in_box))
    lines = ['', "What the simulator counted (`fruit_events`: it judges the measured joint states alone; the planner's "
             f'claims are its `picked` statuses): {len(claimed)} apples claimed picked, **{len(in_box)} in the box**.', '',
             _table(['fate', 'apples', 'which'], rows)]
    if wrong:
        lines += ['', f'<span style="color:red">Claimed picked but not in the box: {", ".join(map(str, wrong))}</span>']
    first = fates.get(n, [])
    lines += ['', f"Scenario 1's apple (apple {n} of the simulator's tree): {', '.join(first) or 'nothing happened to it'}."]
    if worst['bruised'] or worst['knocked']:
        lines += ['', "The planner avoids the scene; its joint moves pass the apples it is not picking no faster than "
                  "the pick cycle's `apple_pass_speed` (0.9 m/s as shipped; 0: full speed) and press none off its "
                  "stem, its straight lines near an apple as they are: the arm knocked "
                  f"{len(worst['knocked'])} of them on the way, {len(worst['bruised'])} faster than the bruising speed."]
    checks = {"every apple the planner calls picked is in the box by the simulator's count": not wrong and bool(in_box),
              "scenario 1's apple is in the box (simulator)": 'in the box' in first}
    return lines, checks


def arc_section(rec, arc_event, arm, names):
    trajectories = rec.messages('planned_trajectory')
    t_recv, msg = trajectories[arc_event['trajectory_index']]
    names_a, t, q, _, _ = planned_arrays(msg, t_recv)
    t_meas, q_meas = measured_arrays(rec.messages('joint_states'), names_a)
    inside = (t_meas >= t[0]) & (t_meas <= t[-1])
    p1, p2, p3 = (np.asarray(p) for p in arc_event['points'])
    tool_plan = arm.fk(q[:, :arm.dof])[:, :3, 3]
    from picking_core.analysis import distance_to_arc_circle
    from picking_core.geometry import Arc
    arc = Arc.through(tool_plan[0], p2, p3)
    dev_plan = distance_to_arc_circle(tool_plan, arc).max()
    dev_meas = distance_to_arc_circle(arm.fk(q_meas[inside, :arm.dof])[:, :3, 3], arc).max()
    return ['', '## Scenario 2: the paper\'s Sec. 3.1 arc', '',
            f'P1 {np.round(p1, 3).tolist()}, P2 {np.round(p2, 3).tolist()}, P3 {np.round(p3, 3).tolist()} m '
            f'(the paper\'s points times {arc_event.get("scale", "?")} m, moved into the workspace): radius '
            f'{arc.radius * 1e3:.1f} mm, sweep {np.degrees(arc.sweep):.1f}°, {t[-1] - t[0]:.2f} s. Largest distance '
            f'of the tool from the arc: planned {dev_plan * 1e3:.3f} mm, measured {dev_meas * 1e3:.3f} mm.']


#: The pick's moments drawn in viewer.png: a label -> the segment it starts.
VIEWER_MOMENTS = {'at home (P0)': None, 'grasping the apple (P2)': 'grasp', 'releasing it over the box (P5)': 'release'}


def viewer_picture(rec, out, t, segments, starts, base='base_link', tool='tool0'):
    """``viewer.png``: what a 3D viewer shows of the recording (the arm's frames from its own /tf and /tf_static,
    through a TF buffer, at the pick's moments; the tool's path; the simulator's world), for readers with no viewer."""
    from picking_common.scene_msgs import scene_from_markers
    from picking_core.frames import TransformBuffer

    from .plots import plot_viewer
    frames = TransformBuffer(cache_time=float('inf'))
    for topic in ('/tf_static', '/tf'):
        for _, msg in rec.messages(topic):
            for tr in msg.transforms:
                v, r = tr.transform.translation, tr.transform.rotation
                frames.set_transform(tr.header.frame_id, tr.child_frame_id, (v.x, v.y, v.z), (r.x, r.y, r.z, r.w),
                                     _stamp(tr.header.stamp), static=topic == '/tf_static')
    names = [f for f in frames.frames() if frames.can_transform(base, f, t[0])]
    links = [(frames.parent(f), f) for f in names if frames.parent(f) in names]
    begins = {label: start for (label, _, _), start in zip(segments, starts)}
    moments = {}
    for label, segment in VIEWER_MOMENTS.items():
        when = begins.get(segment, t[0]) if segment else t[0]
        moments[label] = {f: frames.lookup(base, f, when)[:3, 3] for f in names}
    tool_path = np.array([frames.lookup(base, tool, s)[:3, 3] for s in np.arange(t[0], t[-1], 0.02)])
    world = []
    for _, msg in rec.messages('world_markers')[-1:]:
        for o in scene_from_markers(msg, lambda header: np.eye(4)).obstacles:
            if o.kind == 'box':
                world.append(('box', o.pose, np.asarray(o.size)))
            elif o.ends is not None:
                world.append(('rod', o.ends, o.radius))
    return plot_viewer(out / 'viewer.png', links, moments, tool_path, world,
                       'The pick as a 3D viewer draws its recording (the arm from /tf)')


def _check_mcap(path):
    from mcap_ros2.reader import read_ros2_messages
    return sum(1 for _ in read_ros2_messages(str(path)))


def _plot_error(path, t, err, names, arm_joints):
    """Tracking error over the cycle: the arm's joints (``arm_joints``) in degrees, the gripper (a length) in mm on
    an axis of its own."""
    from .plots import _pyplot, legend_below
    plt = _pyplot()
    arm = [j for j, n in enumerate(names) if n in arm_joints]
    gripper = [j for j, n in enumerate(names) if n not in arm_joints]
    fig, axes = plt.subplots(1 + bool(gripper), 1, sharex=True, figsize=(8, 4.6 + 1.8 * bool(gripper)),
                             gridspec_kw={'height_ratios': [3, 1][:1 + bool(gripper)]}, squeeze=False)
    axes = axes[:, 0]
    for j in arm:
        axes[0].plot(t, np.degrees(err[:, j]), label=names[j])
    axes[0].set_ylabel('joint: measured − planned [°]')
    axes[0].set_title('Tracking error over the pick cycle')
    for j in gripper:
        axes[1].plot(t, err[:, j] * 1e3, color='0.3', label=names[j])
        axes[1].set_ylabel('gripper [mm]')
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel('time [s]')
    legend_below(fig, axes[0])
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
