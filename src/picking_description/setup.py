import glob

from setuptools import find_packages, setup

package_name = 'picking_description'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/urdf', glob.glob('urdf/*')),
        ('share/' + package_name + '/scenes', glob.glob('scenes/*')),
        ('share/' + package_name + '/platforms', glob.glob('platforms/*')),
        ('share/' + package_name + '/viewers', glob.glob('viewers/*')),
    ],
    install_requires=['setuptools'],
    # Test dependencies go in extras_require: tests_require is ignored by colcon
    # with current setuptools, and then colcon test silently runs nothing.
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='Picking arm team',
    maintainer_email='picking-arm@example.org',
    description="The picking arm's description: URDFs with their joint limits, scenes of obstacles, platform layouts, viewer files (Foxglove, RViz), and their lookup.",
    license='Apache-2.0',
)
