from setuptools import find_packages, setup

package_name = 'picking_controller'

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
    description='Steps a JointTrajectory at the controller clock period and publishes joint references.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'picking-controller = picking_controller.start:controller',
            'controller = picking_controller.start:controller',
        ],
    },
)
