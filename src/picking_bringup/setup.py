import glob
import os

from setuptools import find_packages, setup

package_name = 'picking_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # The workspace's parameter files (config/), so that a colcon install finds them in share/picking_bringup/config.
        ('share/' + package_name + '/config', sorted(glob.glob(os.path.join('..', '..', 'config', '*.yaml')))),
        ('share/' + package_name + '/config/arms', sorted(glob.glob(os.path.join('..', '..', 'config', 'arms', '*.yaml')))),
    ],
    install_requires=['setuptools'],
    # Test dependencies go in extras_require: tests_require is ignored by colcon
    # with current setuptools, and then colcon test silently runs nothing.
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='Picking arm team',
    maintainer_email='picking-arm@example.org',
    description='Bringing the picking arm up and using it: picking-stack, picking-goal, picking-plan, the demo with its plots and recording, and the shipped parameter files.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'picking-stack = picking_bringup.stack:main',
            'picking-goal = picking_bringup.picking_goal:main',
            'picking-plan = picking_bringup.plan:main',
            'picking-demo = picking_bringup.demo:main',
            'picking-foxglove = picking_bringup.start:foxglove',
        ],
    },
)
