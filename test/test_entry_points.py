"""Every node's console script starts it through picking_common.startup.quietly (a node stopped while it is still
importing ends quietly: src/picking_common/test/test_startup.py)."""

from importlib.metadata import entry_points

import pytest


@pytest.mark.parametrize('script', ['picking-planner', 'picking-harvester', 'picking-controller', 'picking-sim',
                                    'picking-state-publisher', 'picking-foxglove'])
def test_every_node_s_console_script_starts_it_quietly(script):
    points = [e for e in entry_points(group='console_scripts') if e.name == script]
    assert points, f'{script} is not installed'
    for point in points:
        module = __import__(point.module, fromlist=['_'])
        assert point.module.endswith('.start') and 'quietly' in vars(module), point
