"""The apples as the simulator moves them, judged from the arm's samples alone: hanging and swaying, grasped,
detached, carried and dropped into the box or beside it, a gripper closing beside one, a link knocking one."""

import numpy as np
import pytest

from picking_core.fruit import Fate, FruitWorld, Wind

BOX = (np.array([-0.15, -0.70, -0.01]), np.array([0.25, -0.40, 0.17]))
APPLE = np.array([0.70, 0.10, 0.60])
OPEN, CLOSED = 0.09, 0.055
DT = 0.01


def world(centres=(APPLE,), wind=Wind(), radius=0.04):
    return FruitWorld(np.array(centres), radius, 0.04, BOX, surfaces=[('the platform', [-0.6, -0.8, -0.45], [0.6, 0.8, -0.01])],
                      ground_z=-0.45, wind=wind)


def pose(p):
    T = np.eye(4)
    T[:3, 3] = p
    return T


class Arm:
    """A tool the test moves (its pose and finger opening), with two capsules: the wrist behind the tool and a
    rod (another link) the test places."""

    def __init__(self, w, at, rod=None):
        self.w, self.t, self.at, self.opening, self.rod = w, 0.0, np.asarray(at, float), OPEN, rod
        self.events = []

    def links(self):
        wrist = np.array([self.at - [0.15, 0.0, 0.0], self.at - [0.12, 0.0, 0.0]])
        rod = self.rod if self.rod is not None else np.array([[5.0, 5.0, 5.0], [5.0, 5.0, 5.1]])
        return np.array([wrist, rod])

    def run(self, seconds, to=None, opening=None):
        """Move (straight, at constant speed) to ``to`` and the fingers to ``opening`` over ``seconds``."""
        n = max(1, int(round(seconds / DT)))
        start, o0 = self.at.copy(), self.opening
        end = start if to is None else np.asarray(to, float)
        o1 = o0 if opening is None else opening
        for k in range(1, n + 1):
            s = k / n
            self.at, self.opening = start + s * (end - start), o0 + s * (o1 - o0)
            self.t += DT
            self.events += self.w.observe([self.t], [pose(self.at)], [self.opening], [self.links()],
                                          np.array([0.06, 0.03]), ['wrist', 'rod'])
        return self

    def kinds(self):
        return [e.kind for e in self.events]


def test_a_still_apple_hangs_where_it_grew_and_wind_sways_it_the_same_for_the_same_seed():
    still = Arm(world(), [0.3, 0.1, 0.6]).run(3.0)
    assert np.linalg.norm(still.w.p[0] - APPLE) < 1e-6 and still.events == []
    runs = []
    for _ in range(2):
        windy = world(wind=Wind(amplitude=1.0, frequency=0.8, gust_rate=0.5, gust_strength=2.0, seed=3))
        track = []
        arm = Arm(windy, [0.3, 0.1, 0.6])
        for _ in range(300):
            arm.run(DT)
            track.append(windy.p[0].copy())
        runs.append(np.array(track))
    assert np.array_equal(runs[0], runs[1])
    sway = np.linalg.norm(runs[0] - APPLE, axis=1)
    assert 0.005 < sway.max() < 0.08                         # swings on its stem, never off it
    assert np.allclose(np.linalg.norm(runs[0] - windy.pivot[0], axis=1), windy.length[0], atol=1e-9)


def test_an_apple_grasped_pulled_off_carried_and_let_go_over_the_box_lands_in_it_unbruised():
    arm = Arm(world(), APPLE - [0.10, 0.0, 0.0])
    arm.run(0.5, to=APPLE).run(0.25, opening=CLOSED)
    assert arm.kinds() == ['grasped'] and arm.w.fate[0] == Fate.GRASPED
    arm.run(0.5, to=APPLE - [0.08, 0.0, 0.0])
    assert arm.kinds()[-1] == 'detached' and arm.w.fate[0] == Fate.HELD
    assert np.linalg.norm(arm.w.p[0] - arm.at) < 1e-9       # it moves with the tool
    arm.run(1.5, to=[0.05, -0.55, 0.30]).run(0.25, opening=OPEN).run(1.0)
    assert arm.kinds()[-2:] == ['released', 'in the box'], arm.kinds()
    assert arm.w.fate[0] == Fate.IN_BOX and not arm.w.bruised[0]
    assert arm.w.counts()['in_the_box'] == 1


def test_an_apple_let_go_beside_the_box_is_dropped_on_the_ground_and_bruised():
    arm = Arm(world(), APPLE)
    arm.run(0.25, opening=CLOSED).run(0.5, to=APPLE - [0.08, 0, 0]).run(1.5, to=[0.05, -1.2, 0.30])
    arm.run(0.25, opening=OPEN).run(1.5)
    assert arm.w.fate[0] == Fate.DROPPED and arm.w.landed_on[0] == 'the ground' and arm.w.bruised[0]
    dropped = next(e for e in arm.events if e.kind == 'dropped')
    assert dropped.where[1] == pytest.approx(-1.2, abs=0.05) and 'the ground' in dropped.words


def test_fingers_opened_before_the_stem_gives_leave_the_apple_on_the_tree():
    arm = Arm(world(), APPLE)
    arm.run(0.25, opening=CLOSED).run(0.25, opening=OPEN).run(2.0)
    assert arm.kinds() == ['grasped', 'released on the tree'] and arm.w.fate[0] == Fate.ON_TREE


def test_a_gripper_closing_beside_an_apple_is_a_missed_grasp_of_it_and_a_drive_settling_is_not():
    arm = Arm(world(), APPLE + [0.0, 0.045, 0.0])           # 4.5 cm to the side: outside the fingers
    arm.run(0.05, opening=OPEN - 0.002).run(0.05, opening=OPEN).run(0.05, opening=OPEN - 0.001)
    assert arm.kinds() == []
    arm.run(0.25, opening=CLOSED).run(0.2)
    assert arm.kinds() == ['missed grasp'] and arm.w.misses[0] == 1 and arm.w.fate[0] == Fate.ON_TREE
    assert 'beside it' in arm.events[0].words


def test_a_link_sweeping_through_an_apple_knocks_it_and_a_fast_one_bruises_it():
    for speed, bruised in ((0.3, False), (1.5, True)):
        w = world()
        rod = np.array([[0.70, -0.2, 0.55], [0.70, -0.2, 0.65]])
        arm = Arm(w, [0.2, 0.5, 0.6], rod=rod)
        arm.run(0.01)
        for _ in range(int(0.4 / speed / DT)):                # the rod crosses the apple along +y
            arm.rod = arm.rod + [0.0, speed * DT, 0.0]
            arm.run(DT)
        assert 'knocked' in arm.kinds() and bool(w.bruised[0]) == bruised, (speed, arm.kinds())
        assert w.knocks[0] == 1                               # one contact, one knock


def test_the_fingers_stop_at_the_width_of_the_apple_between_them_and_close_freely_on_air():
    """What a simulated gripper's measured opening shows: the width of what it holds, or its closed opening."""
    arm = Arm(world(), APPLE - [0.10, 0.0, 0.0])
    assert arm.w.finger_stop() == 0.0                        # no sample yet
    arm.run(0.2)
    assert arm.w.finger_stop() == 0.0                        # the apple 10 cm ahead, not between the fingers
    arm.run(0.5, to=APPLE)
    assert arm.w.finger_stop() == pytest.approx(0.08)        # its centre at the grasp point
    arm.run(0.25, opening=0.08).run(0.5, to=APPLE - [0.08, 0.0, 0.0])
    assert arm.w.fate[0] == Fate.HELD and arm.w.finger_stop() == pytest.approx(0.08)   # carried: still in hand
    arm.run(0.1, opening=OPEN)
    assert arm.w.finger_stop() == 0.0                        # let go
    closed = Arm(world(), APPLE - [0.10, 0.0, 0.0]).run(0.25, opening=CLOSED).run(0.5, to=APPLE)
    assert closed.w.finger_stop() == 0.0                     # fingers closed on air are not pushed open by it
