"""The TF buffer against tf2's documented semantics: a tree of frames, transforms over time interpolated, static
ones forever, lookups through the common ancestor at one time, and tf2's errors."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from picking_core.frames import (
    CycleError,
    Disconnected,
    ExtrapolationError,
    InvalidTransform,
    TransformBuffer,
    UnknownFrame,
)

Z90 = Rotation.from_euler('z', 90, degrees=True).as_quat()
I = [0.0, 0.0, 0.0, 1.0]


def point(T, p):
    return (T @ np.append(p, 1.0))[:3]


@pytest.fixture
def tree():
    """world -> base_link (moving along x over 1..3 s), base_link -> camera (static), world -> platform (static),
    platform -> arm2/base_link (static)."""
    b = TransformBuffer()
    for t, x in ((1.0, 1.0), (2.0, 2.0), (3.0, 4.0)):
        b.set_transform('world', 'base_link', [x, 0, 0], I, t)
    b.set_transform('base_link', 'camera', [0.1, 0.0, 0.5], Z90, 0.0, static=True)
    b.set_transform('world', 'platform', [0.0, 5.0, 0.0], I, 0.0, static=True)
    b.set_transform('platform', 'arm2/base_link', [0.0, 0.4, 0.0], I, 0.0, static=True)
    return b


def test_a_static_transform_holds_at_every_time_and_its_inverse_is_the_other_way(tree):
    T = tree.lookup('base_link', 'camera', 123.0)
    assert point(T, [1, 0, 0]) == pytest.approx([0.1, 1.0, 0.5])          # camera x is base y
    assert tree.lookup('camera', 'base_link', 5.0) @ T == pytest.approx(np.eye(4))


def test_transforms_between_stamps_are_interpolated_and_time_zero_is_the_latest_the_chain_knows(tree):
    assert tree.lookup('world', 'base_link', 1.5)[:3, 3] == pytest.approx([1.5, 0, 0])
    assert tree.lookup('world', 'base_link', 2.5)[:3, 3] == pytest.approx([3.0, 0, 0])
    assert tree.lookup('world', 'base_link')[:3, 3] == pytest.approx([4.0, 0, 0])
    b = TransformBuffer()
    b.set_transform('a', 'b', [0, 0, 0], I, 0.0)
    b.set_transform('a', 'b', [0, 0, 0], Z90, 1.0)
    half = Rotation.from_matrix(b.lookup('a', 'b', 0.5)[:3, :3]).as_euler('xyz', degrees=True)
    assert half == pytest.approx([0, 0, 45])                                 # slerp


def test_a_lookup_goes_through_the_common_ancestor(tree):
    # From the camera to the second arm's base: up to world, down through the platform.
    T = tree.lookup('arm2/base_link', 'camera', 2.0)
    expected = [2.0 + 0.1, 0.0, 0.5]                                         # the camera's origin in world
    assert point(T, [0, 0, 0]) == pytest.approx(np.array(expected) - [0.0, 5.4, 0.0])
    assert tree.lookup('/world', 'camera', 2.0) == pytest.approx(tree.lookup('world', '/camera', 2.0))


def test_times_the_chain_does_not_know_are_extrapolation_errors(tree):
    with pytest.raises(ExtrapolationError, match='into the past'):
        tree.lookup('world', 'camera', 0.5)
    with pytest.raises(ExtrapolationError, match="'camera' -> 'world' at 3.500000 s is 0.500 s after the newest"):
        tree.lookup('world', 'camera', 3.5)


def test_unknown_frames_disconnected_trees_and_cycles_are_named(tree):
    with pytest.raises(UnknownFrame, match="frame 'tool9' does not exist"):
        tree.lookup('world', 'tool9')
    tree.set_transform('other_root', 'other', [0, 0, 0], I, 0.0, static=True)
    with pytest.raises(Disconnected, match="'other' hangs from 'other_root'"):
        tree.lookup('world', 'other')
    tree.set_transform('camera', 'world', [0, 0, 0], I, 0.0, static=True)    # world below its own child
    with pytest.raises(CycleError, match='cycle'):
        tree.lookup('world', 'platform')


@pytest.mark.parametrize('translation, quaternion, stamp, match', [
    ([np.nan, 0, 0], I, 0.0, 'not finite'),
    ([0, 0, 0], [0, 0, 0, 0], 0.0, 'zero quaternion'),
    ([0, 0, 0], [np.inf, 0, 0, 1], 0.0, 'not finite'),
    ([0, 0, 0], I, np.nan, 'not finite'),
])
def test_a_transform_that_is_not_one_is_refused_naming_its_frames(translation, quaternion, stamp, match):
    b = TransformBuffer()
    with pytest.raises(InvalidTransform, match=f'a -> b.*{match}|{match}'):
        b.set_transform('a', 'b', translation, quaternion, stamp)
    with pytest.raises(InvalidTransform, match='its own parent'):
        b.set_transform('a', 'a', [0, 0, 0], I, 0.0)


def test_history_older_than_the_cache_time_is_dropped():
    b = TransformBuffer(cache_time=2.0)
    for t in range(10):
        b.set_transform('a', 'b', [t, 0, 0], I, float(t))
    with pytest.raises(ExtrapolationError, match='into the past'):
        b.lookup('a', 'b', 6.0)
    assert b.lookup('a', 'b', 7.5)[0, 3] == pytest.approx(7.5)


def test_random_chains_compose_and_invert_consistently():
    rng = np.random.default_rng(4)
    b = TransformBuffer()
    frames = ['f0']
    for k in range(1, 8):
        parent = frames[rng.integers(len(frames))]
        frames.append(f'f{k}')
        b.set_transform(parent, f'f{k}', rng.normal(size=3), Rotation.random(random_state=k).as_quat(), 0.0,
                        static=True)
    for a in frames:
        for c in frames:
            T_ac = b.lookup(a, c)
            assert T_ac @ b.lookup(c, a) == pytest.approx(np.eye(4), abs=1e-9)
            assert b.lookup(a, 'f0') @ b.lookup('f0', c) == pytest.approx(T_ac, abs=1e-9)
