"""Which command lines take picking-goal's quick stop path (the rest go to its full parser)."""

import pytest

from picking_bringup.stop import DEFAULT_TIMEOUT, stop_asked


@pytest.mark.parametrize('argv, timeout', [
    (['picking-goal', 'stop'], DEFAULT_TIMEOUT),
    (['picking-goal', 'stop', '--timeout', '3'], 3.0),
    (['picking-goal', '--timeout=2.5', 'stop'], 2.5),
    (['picking-goal', 'stop', '--no-wait', '--ros-args', '-r', '__ns:=/arm2'], DEFAULT_TIMEOUT),
])
def test_a_plain_stop_takes_the_quick_path(argv, timeout):
    assert stop_asked(argv) == timeout


@pytest.mark.parametrize('argv', [
    ['picking-goal'], ['picking-goal', 'pose', '0.6', '0.1', '0.4'], ['picking-goal', 'stop', '-h'],
    ['picking-goal', 'stop', '--timeout', 'x'], ['picking-goal', 'stop', '--timeout', '0'],
    ['picking-goal', 'stop', '--timeout', 'inf'], ['picking-goal', 'stop', '--timeout'],
    ['picking-goal', 'stop', 'now'], ['picking-goal', 'stop', '--ros-args', '--timeout', '1'],
])
def test_anything_else_goes_to_the_full_parser(argv):
    assert stop_asked(argv) is None
