"""The offline tool `picking-plan`, run as a user runs it."""

import csv

import numpy as np


def test_paper_reproduces_every_example(run_tool, tmp_path):
    done = run_tool('picking-plan', '--paper', '--out', tmp_path)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert 'minimum acceleration 26.67 deg/s^2' in out
    assert 'blend 0.594 s, blend end 22.40 deg, cruise 24.93 deg/s' in out
    assert 'blend 1.333 s, blend end 39.00 deg, cruise 36.00 deg/s' in out
    assert 'a2 = 30.00, a3 = -6.67' in out
    assert 'centre [10.0, 3.0, 5.0], radius 1' in out
    for name in ('fig9-11_lspb_42.png', 'fig5_cubic_0_90.png', 'fig13_arc.png', 'fig14_via_points.png',
                 'fig12_via_lspb.png', 'chord_error.png', 'fig14_via_points.csv'):
        assert (tmp_path / name).stat().st_size > 1000, name
    with open(tmp_path / 'chord_error.csv') as f:
        rows = list(csv.DictReader(f))
    measured = [float(r['max_distance_measured']) for r in rows]
    assert measured == sorted(measured, reverse=True)
    for r in rows:
        assert float(r['max_distance_measured']) == \
            np.float64(r['max_distance_formula']).round(12) or \
            abs(float(r['max_distance_measured']) / float(r['max_distance_formula']) - 1) < 1e-3


def test_lspb_csv_samples_every_10_ms(run_tool, tmp_path):
    done = run_tool('picking-plan', '--deg', '--out', tmp_path, 'lspb', '--q0', 15, '--qf', 75,
                    '--duration', 3, '--accel', 42)
    assert done.returncode == 0, done.stderr
    data = np.genfromtxt(tmp_path / 'lspb.csv', delimiter=',', names=True)
    assert len(data) == 301
    assert data['t'][1] - data['t'][0] == 0.01
    assert data['q1'][0] == 15.0 and data['q1'][-1] == 75.0
    assert np.abs(data['qdd1']).max() == 42.0


def test_too_little_acceleration_is_refused_with_the_minimum(run_tool, tmp_path):
    done = run_tool('picking-plan', '--deg', '--out', tmp_path, 'lspb', '--q0', 15, '--qf', 75,
                    '--duration', 3, '--accel', 20)
    assert done.returncode == 2
    assert '26.6667' in done.stderr


def test_collinear_arc_is_refused(run_tool, tmp_path):
    done = run_tool('picking-plan', '--out', tmp_path, 'arc', '--p1', 0, 0, 0, '--p2', 1, 1, 1,
                    '--p3', 2, 2, 2)
    assert done.returncode == 2
    assert 'collinear' in done.stderr
