from setuptools import find_packages, setup

package_name = 'picking_sim'

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
    description='Kinematic simulator of the picking arm: servo loop of the paper Fig. 1, publishes joint_states.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'picking-sim = picking_sim.start:sim',
            'sim = picking_sim.start:sim',
            'picking-state-publisher = picking_sim.start:state_publisher',
            'state_publisher = picking_sim.start:state_publisher',
        ],
    },
)
