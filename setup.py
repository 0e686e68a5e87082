"""ament_python packaging: `colcon build` on a ROS 2 machine, `pip install` in a venv."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'epuck_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={
        package_name: ['worlds/*.yaml', 'view/static/*', 'webots/examples/*.py', 'examples/*.py',
                       'examples/epuck2/*.py', 'ros/*.xml', 'urdf/*.urdf']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/worlds', glob('epuck_ros/worlds/*.yaml')),
        ('share/' + package_name + '/urdf', ['epuck_ros/urdf/epuck.urdf']),
    ],
    # A plain `pip install .` runs everything, the `epuck_sim` pytest fixture included (its entry point is in every
    # install): ROS 2 Jazzy from PyPI, and domain_coordinator, which claims the fixture's domain.
    install_requires=['setuptools', 'ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces',
                      'ros-domain-coordinator>=0.12', 'numpy', 'pyyaml', 'mcap', 'zstandard', 'lz4', 'matplotlib',
                      'dask[distributed]', 'gymnasium', 'pettingzoo', 'rosbags', 'foxglove-sdk>=0.30.3,<0.31'],
    extras_require={'test': ['pytest', 'pytest-xdist', 'mcap-ros2-support', 'websocket-client', 'selenium',
                             'yourdfpy', 'flake8', 'pydocstyle']},
    zip_safe=True,
    maintainer='epuck_ros maintainers',
    maintainer_email='maintainers@epuck-ros.invalid',
    description='Fast deterministic e-puck simulator, course behaviours and MCAP tools for ROS 2 Jazzy.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim = epuck_ros.nodes.sim_node:main',
            'forward = epuck_ros.nodes.behaviour_nodes:main_forward',
            'spin = epuck_ros.nodes.behaviour_nodes:main_spin',
            'circle = epuck_ros.nodes.behaviour_nodes:main_circle',
            'rectangle = epuck_ros.nodes.behaviour_nodes:main_rectangle',
            'avoid = epuck_ros.nodes.behaviour_nodes:main_avoid',
            'record = epuck_ros.nodes.record_node:main',
            'bringup = epuck_ros.bringup:main',
            'bag = epuck_ros.bag_cli:main',
            'webots_controller = epuck_ros.webots_controller:main',
            'view = epuck_ros.nodes.view_node:main',
            'teleop = epuck_ros.nodes.teleop_node:main',
            'foxglove = epuck_ros.nodes.foxglove_node:main',
            'sweep = epuck_ros.experiments.cli:main',
            'evolve = epuck_ros.evolution.cli:main',
        ],
        'pytest11': ['epuck_ros = epuck_ros.testing.plugin'],   # a plugin, not an executable
    },
)
