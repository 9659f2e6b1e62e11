"""Where the arm's description lives: URDFs with their joint limits, scenes, platform layouts, viewer files.

The package's data folder is looked up in this order: the ``PICKING_DESCRIPTION`` environment
variable (a folder laid out as this package: ``urdf/``, ``scenes/``, ``platforms/``), the
package's ``share/picking_description`` in a colcon install or a sourced workspace, and the
package's own folder in the source tree (pip editable installs). It imports nothing of the
workspace: every node and tool asks it for paths, never the other way round.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The arm the stack runs unless told otherwise (``urdf/<DEFAULT_ARM>.urdf``).
DEFAULT_ARM = 'picking_arm'


def share_dir() -> Path:
    """The folder holding ``urdf/``, ``scenes/`` and ``platforms/``; FileNotFoundError naming the places looked in."""
    env = os.environ.get('PICKING_DESCRIPTION')
    if env:
        return Path(env)
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('picking_description'))
        if (share / 'urdf' / f'{DEFAULT_ARM}.urdf').exists():
            return share
    except Exception:  # noqa: BLE001 - no ament index (a plain pip install): the source tree
        pass
    here = Path(__file__).resolve().parent.parent
    if (here / 'urdf' / f'{DEFAULT_ARM}.urdf').exists():
        return here
    raise FileNotFoundError('cannot find the picking_description data (urdf/, scenes/, platforms/): not in '
                            'PICKING_DESCRIPTION, the ament index, nor beside the package; set PICKING_DESCRIPTION')


def _existing(path: Path, what: str) -> Path:
    if not path.exists():
        names = sorted(p.name for p in path.parent.glob('*')) if path.parent.exists() else []
        raise FileNotFoundError(f'no {what} {path.name!r} in {path.parent} (there: {", ".join(names) or "nothing"})')
    return path


def urdf_path(arm: str = DEFAULT_ARM) -> Path:
    """The URDF of ``arm`` (its joint limits lie beside it as ``<arm>_joint_limits.yaml``)."""
    return _existing(share_dir() / 'urdf' / f'{arm}.urdf', 'URDF')


def default_urdf() -> Path:
    """The URDF of the arm the nodes run when ``urdf_path`` is empty."""
    return urdf_path(DEFAULT_ARM)


def scene_path(name: str = 'workcell') -> Path:
    """A scene of obstacles (``scenes/<name>_scene.yaml``): ``workcell``, ``orchard`` or ``platform_arm``."""
    return _existing(share_dir() / 'scenes' / f'{name}_scene.yaml', 'scene')


def platform_path(name: str = 'platform') -> Path:
    """A platform's layouts of arms (``platforms/<name>.yaml``)."""
    return _existing(share_dir() / 'platforms' / f'{name}.yaml', 'platform file')


def viewer_path(name: str = 'picking_arm.foxglove.json') -> Path:
    """A viewer's file (``viewers/<name>``): ``picking_arm.foxglove.json`` (a Foxglove layout) or ``picking_arm.rviz``."""
    return _existing(share_dir() / 'viewers' / name, 'viewer file')
