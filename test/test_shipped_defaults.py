"""A node started bare behaves as shipped: every parameter's default is the value the shipped files give it."""

import pytest
import yaml

from picking_bringup.shipped import config_dir
from picking_bringup.stack import NODES
from picking_controller.parameters import PARAMS as CONTROLLER
from picking_planner.parameters import PARAMS as PLANNER
from picking_sim.parameters import PARAMS as SIM

TABLES = {'picking_planner': PLANNER, 'picking_controller': CONTROLLER, 'picking_sim': SIM}


def shipped(node):
    """The values picking-stack's files give ``node`` (nested keys flattened with dots)."""
    files = next(files for name, files in NODES.values() if name == node)
    out = {}
    for f in files:
        for key, value in yaml.safe_load((config_dir() / f).read_text())[f'/**/{node}']['ros__parameters'].items():
            if isinstance(value, dict):
                out.update({f'{key}.{k}': v for k, v in value.items()})
            else:
                out[key] = value
    return out


@pytest.mark.parametrize('node', sorted(TABLES))
def test_every_default_is_the_shipped_value(node):
    values = shipped(node)
    differ = {p.name: (p.default, values[p.name]) for p in TABLES[node]
              if p.name in values and values[p.name] != p.default}
    assert differ == {}, f'{node}: default != shipped for {differ}'
