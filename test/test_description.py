"""The URDF parses with yourdfpy and holds the model's figures; the shipped file is the generator's output."""
from __future__ import annotations

import math
import subprocess
import sys
from io import BytesIO

import numpy as np
import pytest
import yourdfpy

from epuck_ros.description import JOINT_NAMES, URDF_FILE, urdf
from epuck_ros.model import CAMERA_POSE, SENSOR_HEIGHT, SENSOR_NAMES, SENSOR_POSES, RobotModel


def parse(text: str) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(BytesIO(text.encode()), build_scene_graph=True, load_meshes=False)


def planar(matrix: np.ndarray) -> tuple[float, float, float, float]:
    """x, y, z and yaw of a homogeneous transform without roll or pitch."""
    assert matrix[2, 2] == pytest.approx(1.0, abs=1e-12), 'no roll or pitch'
    return matrix[0, 3], matrix[1, 3], matrix[2, 3], math.atan2(matrix[1, 0], matrix[0, 0])


def test_the_shipped_urdf_is_generated_from_the_model():
    assert URDF_FILE.read_text() == urdf(), 'regenerate: python -m epuck_ros.description > epuck_ros/urdf/epuck.urdf'
    output = subprocess.run([sys.executable, '-m', 'epuck_ros.description'], capture_output=True, text=True,
                            check=True).stdout
    assert output == URDF_FILE.read_text()


def test_wheels_axle_and_sensor_poses_match_the_model():
    model = RobotModel()
    robot = parse(URDF_FILE.read_text())
    assert robot.validate()
    assert robot.actuated_joint_names == JOINT_NAMES
    for joint in JOINT_NAMES:
        assert robot.joint_map[joint].type == 'continuous'
        assert list(robot.joint_map[joint].axis) == [0.0, 1.0, 0.0]
    for link in ('left_wheel', 'right_wheel'):
        assert robot.link_map[link].visuals[0].geometry.cylinder.radius == model.wheel_radius
    left, right = (robot.get_transform(link, 'base_link')[:3, 3] for link in ('left_wheel', 'right_wheel'))
    assert left[1] - right[1] == pytest.approx(model.wheel_separation, abs=1e-15)
    assert left[2] == right[2] == model.wheel_radius   # the hinges sit one radius above the floor
    for name, (x, y, yaw) in zip(SENSOR_NAMES, SENSOR_POSES):
        assert planar(robot.get_transform(name, 'base_link')) == pytest.approx((x, y, SENSOR_HEIGHT, yaw), abs=1e-12)
    assert planar(robot.get_transform('camera', 'base_link')) == pytest.approx((*CAMERA_POSE, 0.0), abs=1e-15)
    assert robot.link_map['base_link'].collisions[0].geometry.cylinder.radius == model.body_radius


def test_a_prefix_names_every_link_and_joint():
    robot = parse(urdf(prefix='epuck3/'))
    assert robot.validate()
    assert all(name.startswith('epuck3/') for name in [*robot.link_map, *robot.joint_map])
    assert robot.actuated_joint_names == [f'epuck3/{joint}' for joint in JOINT_NAMES]
    assert planar(robot.get_transform('epuck3/ps3', 'epuck3/base_link')) == pytest.approx(
        (*SENSOR_POSES[3][:2], SENSOR_HEIGHT, SENSOR_POSES[3][2]), abs=1e-12)
