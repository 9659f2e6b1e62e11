"""Row 11: a swaying apple picked, counted by the fruit world. One apple on its stem in front of the shipped arm,
swayed by the simulator's wind; the camera's detections at 30 Hz, 50 ms late, 3 mm noise; the pick planned by the
shipped cycle aimed three ways (picking_sim.sway_pick): at where the sway fit predicts the apple will be when the
fingers close, re-targeted at each detection, waiting at the stand-off while the closing is not sure (ours); at the
latest detection, re-targeted the same way (prediction off); at the detection when the pick starts (tracking off).
Each played through the world, which says whether the apple ended in the box and where it was when the fingers
closed. The arm follows its plans exactly here (the servo's lag is the simulator's)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from picking_bringup.shipped import shipped_harvest
from picking_core.collision import Scene
from picking_core.fruit import Wind
from picking_core.harvest import SIDEWAYS
from picking_core.kinematics.capsules import ArmCapsules
from picking_description import scene_path
from picking_sim.orchard import ArmSamples, fruit_world
from picking_sim.sway_pick import MODES, pick_swaying

#: m: the apple, in front of the arm (the demo's).
APPLE = np.array([0.70, 0.15, 0.65])
#: Runs of each case (the apple's size, stem, phase and the camera's noise drawn from the seed); the rows with goals
#: (ours, at ±30 mm and 1 Hz) have more, so that their p95 is no single pick's.
SEEDS = range(12)
GOAL_SEEDS = range(48)
#: m/s² of wind push that sways the simulator's apples about ±30 mm at 1 Hz; the sweep's cases.
PUSH = 2.4
SWEEP = ((0.5, 2.4, 0.0), (2.0, 2.4, 0.0), (1.0, 1.2, 0.0), (1.0, 3.6, 0.0), (1.0, 2.4, 1.0))
#: s the camera watches before the pick starts: the wind starts the apple from rest, and its sway is steady (the
#: start-up transient died away) after about 5 s; the row is about a swaying apple, not one just set swinging.
WATCH = 5.0
#: rad: the wind across the approach (the fingers' width, their tightest way) and along it.
DIRECTIONS = {'across': np.pi / 2, 'along': 0.0}


def _runs(cycle, samples, scene, mode, frequency, push, gusts, direction, riding=True, seeds=SEEDS):
    rotation = Rotation.from_euler('xyz', SIDEWAYS).as_matrix()
    out, sway = [], []
    for seed in seeds:
        wind = Wind(amplitude=push, frequency=frequency, direction=direction, gust_rate=gusts, gust_strength=push,
                    seed=seed)
        world = fruit_world(APPLE[None], scene, seed=seed, wind=wind)
        out.append(pick_swaying(cycle, samples, world, 0, rotation, mode, watch=WATCH, seed=seed, riding=riding))
        sway.append(_amplitude(frequency, push, gusts, direction, seed, scene))
    return out, float(np.median(sway))


def _amplitude(frequency, push, gusts, direction, seed, scene):
    """m: half the sway's peak-to-peak along the wind, the arm away (the seconds before a pick)."""
    wind = Wind(amplitude=push, frequency=frequency, direction=direction, gust_rate=gusts, gust_strength=push,
                seed=seed)
    world = fruit_world(APPLE[None], scene, seed=seed, wind=wind)
    far, rod = np.eye(4), np.array([[[5.0, 5.0, 5.0], [5.0, 5.0, 5.1]]])
    far[:3, 3] = 5.0
    p = []
    for t in np.arange(0.01, 6.0, 0.01):
        world.observe([t], [far], [0.09], [rod], np.array([0.03]))
        p.append(world.p[0].copy())
    heading = np.array([np.cos(direction), np.sin(direction), 0.0])
    along = np.array(p)[300:] @ heading
    return float(np.ptp(along) / 2)


def _figures(runs):
    misses = np.array([r.miss if r.miss is not None else np.nan for r in runs])
    closed = misses[np.isfinite(misses)]
    return {'in_box': 100.0 * np.mean([r.in_box for r in runs]),
            'median': 1e3 * np.median(closed) if len(closed) else np.nan,
            'p95': 1e3 * np.percentile(closed, 95) if len(closed) else np.nan,
            'cycle': float(np.median([r.cycle for r in runs])),
            'bruised': int(sum(r.bruised for r in runs)),
            'waited': int(sum(r.held > 0 for r in runs)), 'backed_off': int(sum(r.backed_off for r in runs))}


def _waits(f):
    """How many picks waited at the stand-off and how many backed off without closing, in words."""
    return f"; {f['waited']} waited at the stand-off for a sure closing, {f['backed_off']} backed off without closing"


def swaying_apples():
    """Rows 11: the swaying apple in the box on the first attempt, the miss at closing, the cycle, per aim."""
    cycle = shipped_harvest().cycle
    samples = ArmSamples(cycle.arm, ArmCapsules.from_arm(cycle.arm), [*cycle.arm.joint_names, 'gripper_joint'])
    scene = Scene.from_yaml(scene_path('workcell'))
    # (A still apple's pick is not aimed, so not slowed to ride it: the plan it gets today.)
    still = _figures(_runs(cycle, samples, scene, 'predicted', 1.0, 0.0, 0.0, 0.0, riding=False)[0])
    rows = []
    for where, direction in DIRECTIONS.items():
        for mode in MODES:
            ours = mode == 'predicted'
            runs, amplitude = _runs(cycle, samples, scene, mode, 1.0, PUSH, 0.0, direction,
                                    seeds=GOAL_SEEDS if ours else SEEDS)
            f = _figures(runs)
            print(f'  1 Hz ±{amplitude * 1e3:.0f} mm {where}, {mode}: {f}', flush=True)
            ok = f['in_box'] >= 95 and f['median'] <= 2 and f['p95'] <= 5 and f['bruised'] == 0 and \
                f['cycle'] <= 1.15 * still['cycle']
            rows.append(['11', f'a swaying apple picked, the world\'s count (1 Hz ±{amplitude * 1e3:.0f} mm {where} the '
                               f'approach; aimed at {_AIMS[mode]})',
                         f"{f['in_box']:.0f} % in the box",
                         f"{len(runs)} picks; miss at closing median {f['median']:.1f} mm, p95 {f['p95']:.1f} mm; "
                         f"cycle {f['cycle']:.2f} s (a still apple's {still['cycle']:.2f} s, miss median "
                         f"{still['median']:.1f} mm); {f['bruised']} bruised" + (_waits(f) if ours else ''),
                         '≥ 95 %, miss ≤ 2 / 5 mm, cycle ≤ 1.15x still, 0 bruised' if ours else '—',
                         ('meets' if ok else 'misses') if ours else '—'])
    for frequency, push, gusts, direction in ((*case[:2], case[2], DIRECTIONS['across']) for case in SWEEP):
        runs, amplitude = _runs(cycle, samples, scene, 'predicted', frequency, push, gusts, direction)
        f = _figures(runs)
        label = f'{frequency:g} Hz ±{amplitude * 1e3:.0f} mm' + (f', gusts {gusts:g}/s' if gusts else '')
        print(f'  {label}: {f}', flush=True)
        rows.append(['11', f'the same, aimed at the prediction: {label} across the approach',
                     f"{f['in_box']:.0f} % in the box",
                     f"{len(runs)} picks; miss median {f['median']:.1f} mm, p95 {f['p95']:.1f} mm; cycle "
                     f"{f['cycle']:.2f} s; {f['bruised']} bruised" + _waits(f), '—', '—'])
    return rows


_AIMS = {'predicted': "the sway fit's prediction, re-targeted at 30 Hz",
         'latest': 'the latest detection, re-targeted at 30 Hz (prediction off)',
         'fixed': "the detection at the pick's start (tracking off)"}


if __name__ == '__main__':
    for row in swaying_apples():
        print(' | '.join(str(x) for x in row))
