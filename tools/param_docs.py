"""Write docs/parameters.md from the nodes' parameter tables (``make docs``; a test checks it is current).

Each node's parameters are a table of picking_common.params.Param in its package (``parameters.py``):
the nodes declare them with these descriptors, so this page, ``ros2 param describe`` and the shipped
files say the same. Usage: python tools/param_docs.py [--check]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / 'docs' / 'parameters.md'


def shipped(node, files):
    """The values the shipped parameter files give ``node`` (nested keys flattened with dots)."""
    out = {}
    for f in files:
        data = yaml.safe_load((ROOT / 'config' / f).read_text())[f'/**/{node}']['ros__parameters']
        for key, value in data.items():
            if isinstance(value, dict):
                out.update({f'{key}.{k}': v for k, v in value.items()})
            else:
                out[key] = value
    return out


def page():
    from picking_bringup.foxglove import PARAMS as FOXGLOVE
    from picking_common.params import markdown
    from picking_controller.parameters import PARAMS as CONTROLLER
    from picking_planner.parameters import HARVESTER
    from picking_planner.parameters import PARAMS as PLANNER
    from picking_sim.parameters import PARAMS as SIM
    from picking_sim.parameters import STATE_PUBLISHER
    parts = ['# Parameters', '',
             'Every parameter of every node, as the node declares it (`ros2 param describe` shows the same '
             'description, range and read-only flag). *shipped* is the value in the `config/` files that '
             '`picking-stack` and the README start the nodes with; *read-only* parameters are set at start '
             '(`-p`, a params file) and a `ros2 param set` of one is refused; the others take effect at once, '
             'checked first (a value out of range, or one the node cannot work with, is refused with the '
             'reason). A key in a params file that the node does not have is reported when it starts. '
             'Written by `tools/param_docs.py` from `src/<package>/<package>/parameters.py`.', '']
    for node, params, files in (('picking_sim', SIM, ('sim.yaml',)),
                                ('picking_controller', CONTROLLER, ('controller.yaml',)),
                                ('picking_planner', PLANNER, ('planner.yaml', 'pick_cycle.yaml')),
                                ('picking_state_publisher', STATE_PUBLISHER, ()),
                                ('picking_harvester', HARVESTER, ()),
                                ('picking_foxglove', FOXGLOVE, ())):
        parts += [f'## {node}', '', markdown(params, shipped(node, files)), '']
    parts += ['`config/paper_methods.yaml` sets the planner\'s methods back to the paper\'s (`picking-stack --paper`).',
              '']
    return '\n'.join(parts)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--check', action='store_true', help='exit 1 if docs/parameters.md is not current')
    args = parser.parse_args(argv)
    text = page()
    if args.check:
        if OUT.read_text() != text:
            print(f'{OUT} is not current: run python tools/param_docs.py', file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text)
    print(f'wrote {OUT}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
