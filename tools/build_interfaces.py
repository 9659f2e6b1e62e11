"""Build the workspace's interface packages (ament_cmake + rosidl) into this Python's prefix.

The pip route of ROS 2 Jazzy has no control_msgs wheel, so ``make`` builds ours
(src/control_msgs, the FollowJointTrajectory action) and the project's own actions
(src/picking_interfaces) with the rosidl generators from the wheels, and installs them into
the virtual environment: they import like the wheels' messages, with no setup.bash.

Two things the wheels need first: their exported ``*_rosidl_generator_pyExport.cmake`` files
name the Python include and site-packages directories of the image that built them, where CMake
stops ("non-existent path"); they are pointed at this Python's. A package another prefix on
AMENT_PREFIX_PATH already provides (a sourced Jazzy with ros-jazzy-control-msgs) is not built.

Usage: python tools/build_interfaces.py [--build-dir DIR] [PACKAGE ...]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ('control_msgs', 'tf2_msgs', 'vision_msgs', 'picking_interfaces')       # in build order


def point_exports_here(prefix):
    """Point the wheels' pyExport files at this Python's headers and site-packages; returns how many changed."""
    include, site = sysconfig.get_paths()['include'], sysconfig.get_paths()['purelib']
    if not Path(include, 'Python.h').exists():
        raise SystemExit(f"Python's headers are missing ({include}/Python.h): install python3-dev")
    changed = 0
    for path in Path(prefix, 'share').glob('*/cmake/*_rosidl_generator_pyExport.cmake'):
        text = path.read_text()
        new = re.sub(r'/opt/python/[^/;"]+/include/python3\.\d+', include, text)
        new = re.sub(r'/opt/python/[^/;"]+/lib/python3\.\d+/site-packages', site, new)
        if new != text:
            path.write_text(new)
            changed += 1
    return changed


def provided_elsewhere(package, prefix):
    """The other prefix on AMENT_PREFIX_PATH that already has ``package``, or None."""
    for other in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        if Path(other).resolve() != Path(prefix).resolve() and \
                Path(other, 'share', 'ament_index', 'resource_index', 'packages', package).exists():
            return other
    return None


def build(package, prefix, build_dir):
    started = time.monotonic()
    source = ROOT / 'src' / package
    out = Path(build_dir) / package
    env = dict(os.environ, CMAKE_PREFIX_PATH=os.pathsep.join(
        filter(None, [str(prefix), os.environ.get('CMAKE_PREFIX_PATH', '')])))
    for cmd in (['cmake', '-S', str(source), '-B', str(out), f'-DCMAKE_INSTALL_PREFIX={prefix}',
                 f'-DPython3_EXECUTABLE={sys.executable}', '-DBUILD_TESTING=OFF', '-DCMAKE_BUILD_TYPE=Release',
                 '--log-level=WARNING'],
                ['cmake', '--build', str(out), '-j', str(os.cpu_count() or 2)],
                ['cmake', '--install', str(out)]):
        done = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            sys.stderr.write(done.stdout[-4000:] + done.stderr[-4000:])
            raise SystemExit(f'building {package} failed: {" ".join(cmd)}')
    print(f'{package}: built and installed into {prefix} in {time.monotonic() - started:.0f} s')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('packages', nargs='*', default=PACKAGES, help=f'default: {" ".join(PACKAGES)}')
    parser.add_argument('--build-dir', default=str(ROOT / 'build' / 'interfaces'))
    args = parser.parse_args(argv)
    prefix = sys.prefix
    point_exports_here(prefix)
    for package in args.packages:
        other = provided_elsewhere(package, prefix)
        if other:
            print(f'{package}: provided by {other}; not built')
            continue
        build(package, prefix, args.build_dir)


if __name__ == '__main__':
    main()
