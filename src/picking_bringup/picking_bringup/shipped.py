"""The shipped configuration: the nodes' parameter files and the arm, tree and harvest they make.

The parameter files (``planner.yaml``, ``pick_cycle.yaml``, ``controller.yaml``, ``sim.yaml``,
``paper_methods.yaml``) are looked up in this order: the ``PICKING_CONFIG`` environment variable
(a folder), ``share/picking_bringup/config`` of a colcon install, and the workspace's ``config/``
(pip editable installs). The arm, scenes and platforms are the description package's.
"""

from __future__ import annotations

import os
from pathlib import Path

from picking_description import DEFAULT_ARM, scene_path, urdf_path

#: The planner's parameter files, in the order picking-stack gives them.
PLANNER_FILES = ('planner.yaml', 'pick_cycle.yaml')


def arm_files(arm=None):
    """The parameter files an arm adds after the shipped ones (``arms/<arm>.yaml``; none for the default arm)."""
    return () if arm in (None, DEFAULT_ARM) else (f'arms/{arm}.yaml',)


def check_arm(config, arm):
    """ValueError naming the shipped arms unless ``config`` (the parameter files' folder) has ``arms/<arm>.yaml``."""
    if not (Path(config) / 'arms' / f'{arm}.yaml').exists():
        shipped = sorted(p.stem for p in (Path(config) / 'arms').glob('*.yaml'))
        raise ValueError(f'no arm {arm!r}: config/arms has {", ".join(shipped) or "none"}')


def config_dir() -> Path:
    """The folder of the nodes' parameter files; FileNotFoundError when none is found."""
    env = os.environ.get('PICKING_CONFIG')
    if env:
        return Path(env)
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('picking_bringup')) / 'config'
        if (share / 'planner.yaml').exists():
            return share
    except Exception:  # noqa: BLE001 - no ament index (a plain pip install): the source tree
        pass
    for parent in Path(__file__).resolve().parents:
        if (parent / 'config' / 'planner.yaml').exists():
            return parent / 'config'
    raise FileNotFoundError('cannot find the parameter files (config/planner.yaml); set PICKING_CONFIG to their folder')


def shipped_harvest(config=None, arm=None, **overrides):
    """The :class:`~picking_core.harvest.Harvest` the shipped planner plans with on ``arm`` (a shipped arm's
    name; default: the picking arm); ``overrides``: planner parameters on top, e.g. an arm's own
    ``box_position``."""
    from picking_core.platform import load_harvest
    folder = Path(config) if config else config_dir()
    return load_harvest(urdf_path(arm or DEFAULT_ARM), [folder / name for name in (*PLANNER_FILES, *arm_files(arm))],
                        **overrides)


def shipped_orchard(n, seed=0, arm=None, config=None):
    """A seeded orchard tree of ``n`` apples in front of the shipped ``arm`` at its home, in its workcell
    (:func:`picking_core.orchard.orchard_tree`)."""
    from picking_core.collision import Scene
    from picking_core.orchard import orchard_tree
    cycle = shipped_harvest(config, arm).cycle
    return orchard_tree(n, seed, cycle.arm, Scene.from_yaml(scene_path('workcell')), cycle.s.home_positions)
