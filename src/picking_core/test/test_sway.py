"""Where a swaying apple will be: the motion model fitted to a camera's stamped detections of the simulator's own
swaying apples (its pendulums and wind), against the truth, and against the latest detection as a target."""

import numpy as np
import pytest

from picking_core.fruit import FruitWorld, Wind
from picking_core.sway import Sightings, SwayFit

BOX = (np.array([-0.15, -0.70, -0.01]), np.array([0.25, -0.40, 0.17]))
APPLE = np.array([0.70, 0.10, 0.60])
NOISE, RATE = 0.003, 30.0
R = np.eye(3) * NOISE ** 2


def swaying(frequency, push, seconds=7.0, gusts=0.0, seed=1, dt=0.002):
    """The simulator's apple on a 4 cm stem in a wind at ``frequency`` Hz pushing ``push`` m/s²: times and true
    centres every ``dt`` s (the arm far away)."""
    world = FruitWorld(APPLE[None], 0.04, 0.04, BOX, wind=Wind(amplitude=push, frequency=frequency, gust_rate=gusts,
                                                               gust_strength=3 * push, seed=seed))
    far = np.eye(4)
    far[:3, 3] = 5.0
    rod = np.array([[[5.0, 5.0, 5.0], [5.0, 5.0, 5.1]]])
    t = np.arange(1, int(seconds / dt) + 1) * dt
    p = []
    for ti in t:
        world.observe([ti], [far], [0.09], [rod], np.array([0.03]))
        p.append(world.p[0].copy())
    return t, np.array(p)


def watched(t, p, horizon, after=3.0, seed=0):
    """A camera's detections at RATE (noise NOISE) fed to a SwayFit; from ``after`` s on, at each frame, the error
    of the prediction ``horizon`` s past its stamp, of the latest detection as the target, and the predicted σ."""
    rng = np.random.default_rng(seed)
    fit, out = SwayFit(), []
    for stamp in np.arange(0.1, t[-1] - horizon, 1.0 / RATE):
        i = np.searchsorted(t, stamp)
        z = p[i] + rng.normal(0.0, NOISE, 3)
        assert fit.update(stamp, z, R)
        if stamp >= after:
            truth = p[np.searchsorted(t, stamp + horizon)]
            mean, cov = fit.predict(stamp + horizon)
            out.append((np.linalg.norm(mean - truth), np.linalg.norm(z - truth),
                        np.linalg.norm((mean - truth) / np.sqrt(np.diag(cov)))))
    return fit, np.array(out)


def test_an_apple_swaying_30_mm_at_1_hz_is_predicted_where_it_will_be_within_a_few_millimetres():
    """Predicted past the newest capture by a camera's latency and the fingers' closing time together."""
    t, p = swaying(1.0, 2.4)
    assert 0.025 < np.ptp(p[len(p) // 2:, 0]) / 2 < 0.04                # the ±30 mm sway of the issue
    fit, e = watched(t, p, 0.15)
    assert fit.fit().frequency == pytest.approx(1.0, abs=0.02)
    assert np.median(e[:, 0]) < 0.003 and np.percentile(e[:, 0], 95) < 0.007
    assert np.median(e[:, 0]) < np.median(e[:, 1]) / 5                   # the latest detection as a target
    assert np.mean(e[:, 2] < 3 * np.sqrt(3)) > 0.95                     # its covariance covers the error


@pytest.mark.parametrize('frequency', [0.5, 2.0])
def test_the_sway_frequency_is_found_across_the_winds_range(frequency):
    t, p = swaying(frequency, 2.4)
    fit, e = watched(t, p, 0.1)
    assert fit.fit().frequency == pytest.approx(frequency, abs=0.02)
    assert np.median(e[:, 0]) < 0.004


def test_a_still_apple_is_its_mean_and_a_gust_makes_the_prediction_uncertain():
    t, p = swaying(1.0, 0.0)
    fit, e = watched(t, p, 0.3)
    f = fit.fit()
    assert f.frequency == 0.0 and np.linalg.norm(f.centre - APPLE) < 0.002
    mean, cov = fit.predict(t[-1] + 0.3)
    assert np.linalg.norm(mean - APPLE) < 0.002 and np.sqrt(cov.max()) < 0.002
    steady = watched(*swaying(1.0, 2.4, seed=4), 0.3)[1]
    gusty = watched(*swaying(1.0, 2.4, gusts=1.0, seed=4), 0.3)[1]
    sigma = [np.median(e[:, 0] / e[:, 2]) for e in (steady, gusty)]   # the predicted σ (norm over the axes)
    assert np.median(gusty[:, 0]) > 5 * np.median(steady[:, 0])       # gusts are not a steady sway ...
    assert sigma[1] > 4 * sigma[0] and sigma[1] > 0.005               # ... and the prediction says it is unsure


def test_detections_out_of_order_or_not_finite_are_refused_and_a_long_gap_starts_over():
    fit = SwayFit()
    assert fit.predict(1.0) is None and fit.fit() is None
    assert fit.update(1.0, APPLE, R) and fit.update(1.1, APPLE, R)
    assert not fit.update(1.05, APPLE + 0.1, R)                         # older than the newest one applied
    assert not fit.update(1.2, [np.nan, 0.0, 0.0], R) and not fit.update(1.2, APPLE, R * np.inf)
    assert not fit.update(np.nan, APPLE, R)
    assert fit.refused == 4 and np.allclose(fit.predict(1.2)[0], APPLE)
    assert fit.update(5.0, APPLE + 0.05, R)                              # after a gap: the new place alone
    assert np.allclose(fit.predict(5.0)[0], APPLE + 0.05)


def test_the_fruit_map_predicts_each_tracked_apple_from_its_own_detections():
    from picking_core.fruit_map import FruitMap
    t, p = swaying(1.0, 2.4)
    rng = np.random.default_rng(2)
    still = np.array([0.6, -0.2, 0.7])
    fruit_map = FruitMap()
    for stamp in np.arange(0.1, 5.0, 1.0 / RATE):
        moving = p[np.searchsorted(t, stamp)]
        z = np.array([moving, still]) + rng.normal(0.0, NOISE, (2, 3))
        fruit_map.update(stamp, z, np.array([R, R]), np.array([0.08, 0.07]))
    swinging, hanging = sorted(fruit_map.targets(), key=lambda k: k.x[0], reverse=True)
    ahead = stamp + 0.15
    assert np.linalg.norm(fruit_map.predict(swinging.id, ahead)[0] - p[np.searchsorted(t, ahead)]) < 0.006
    assert np.linalg.norm(fruit_map.predict(hanging.id, ahead)[0] - still) < 0.002
    assert hanging.motion.fit().frequency == 0.0 and fruit_map.predict(10 ** 6, ahead) is None


def test_sightings_follow_one_apple_back_and_leave_out_one_carried_past_it():
    """Frames of an apple swaying ±30 mm at 1 Hz: followed back from the newest frame. In one frame it is hidden
    while another apple (carried by the arm) passes 4 cm from where it hangs: that one is not taken for it."""
    sightings = Sightings(window=2.0)
    rest = np.array([0.7, 0.15, 0.65])
    for k in range(90):
        t = k / 30
        here = rest + [0.0, 0.03 * np.sin(2 * np.pi * t), 0.0]
        places = [here, rest + [0.0, 0.2, 0.0]] if k != 40 else [rest + [0.0, -0.04, 0.0], rest + [0.0, 0.2, 0.0]]
        sightings.add(t, places, [0.08, 0.07])
    seen = sightings.of(rest, 0.05)
    assert len(seen) == 60 - 1 and seen[0][0] >= 3.0 - 2.0 - 1e-9            # the window, less the hidden frame
    assert all(abs(p[1] - rest[1] - 0.03 * np.sin(2 * np.pi * t)) < 1e-9 for t, p, _ in seen)
    assert all(d == 0.08 for _, _, d in seen)
