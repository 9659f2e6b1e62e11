from setuptools import find_packages, setup

package_name = 'picking_planner'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    # Test dependencies go in extras_require: tests_require is ignored by colcon
    # with current setuptools, and then colcon test silently runs nothing.
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='Picking arm team',
    maintainer_email='picking-arm@example.org',
    description='The planner node: pose goals, paths, picks and harvests to joint trajectories for the controller; the coordinator of several arms.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'picking-planner = picking_planner.start:planner',
            'picking-harvester = picking_planner.start:harvester',
            'planner = picking_planner.start:planner',
            'harvester = picking_planner.start:harvester',
        ],
    },
)
