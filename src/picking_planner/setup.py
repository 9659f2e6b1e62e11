import glob
import os

from setuptools import find_packages, setup

package_name = 'picking_planner'
# The workspace's config/ (URDFs, joint limits, node parameters) is installed with
# this package, so that a colcon install finds it in share/picking_planner/config.
config_files = sorted(glob.glob(os.path.join('..', '..', 'config', '*')))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', config_files),
    ],
    install_requires=['setuptools'],
    # Test dependencies go in extras_require: tests_require is ignored by colcon
    # with current setuptools, and then colcon test silently runs nothing.
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='Picking arm team',
    maintainer_email='picking-arm@example.org',
    description='Pose goals to joint trajectories: kinematics, IK, cubic/quintic/LSPB profiles, Cartesian lines and arcs, the pick cycle.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'picking-plan = picking_planner.cli.plan:main',
            'picking-planner = picking_planner.node:main',
            'picking-goal = picking_planner.cli.goal:main',
            'picking-demo = picking_planner.cli.demo:main',
            'picking-stack = picking_planner.cli.stack:main',
            'picking-harvester = picking_planner.harvester:main',
            'planner = picking_planner.node:main',
        ],
    },
)
