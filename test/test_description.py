"""The URDF parses with yourdfpy and holds the model's figures; the shipped file is the generator's output."""
from __future__ import annotations

import math
import subprocess
import sys
from io import BytesIO

import numpy as np
import pytest
import yourdfpy

from epuck_ros import description
from epuck_ros.description import IMU_FRAME, JOINT_NAMES, URDF_FILE, FixedFrame, sensor_frames, urdf
from epuck_ros.model import (CAMERA_POSE, GROUND_SENSOR_NAMES, GROUND_SENSOR_POSES, IMU_POSITION, LIGHT_SENSOR_HEIGHT,
                             LIGHT_SENSOR_NAMES, SENSOR_HEIGHT, SENSOR_NAMES, SENSOR_POSES, RobotModel)


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


def test_light_and_ground_sensors_and_the_imu_sit_at_the_models_poses():
    """ls0..ls7 on the IR sensors' bearings; gs0..gs2 with x along their rays, straight down; imu at the origin."""
    robot = parse(URDF_FILE.read_text())
    assert robot.validate()
    for name, (x, y, yaw) in zip(LIGHT_SENSOR_NAMES, SENSOR_POSES):
        assert planar(robot.get_transform(name, 'base_link')) == pytest.approx((x, y, LIGHT_SENSOR_HEIGHT, yaw),
                                                                               abs=1e-12)
    for name, xyz in zip(GROUND_SENSOR_NAMES, GROUND_SENSOR_POSES):
        matrix = robot.get_transform(name, 'base_link')
        assert matrix[:3, 3] == pytest.approx(xyz, abs=1e-15)
        assert matrix[:3, :3] == pytest.approx(np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]), abs=1e-15)  # x down
    imu = robot.get_transform(IMU_FRAME, 'base_link')
    assert imu[:3, 3] == pytest.approx(IMU_POSITION, abs=0) and imu[:3, :3] == pytest.approx(np.eye(3), abs=0)


def rotation(quaternion: tuple[float, float, float, float]) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = quaternion
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_every_frame_of_tf_static_is_the_urdfs(monkeypatch):
    """The translations and quaternions /tf_static carries are the URDF's origins, rpy read by yourdfpy (one frame
    both pitched and yawed added: the order of the two rotations)."""
    frames = sensor_frames() + [FixedFrame('turned', (0.01, 0.02, 0.03), yaw=0.7, pitch=0.4)]
    shipped = set(parse(URDF_FILE.read_text()).link_map) - {'base_link', 'left_wheel', 'right_wheel'}
    assert {frame.name for frame in frames[:-1]} == shipped
    monkeypatch.setattr(description, 'sensor_frames', lambda model: frames)
    robot = parse(urdf())
    for frame in frames:
        matrix = robot.get_transform(frame.name, 'base_link')
        assert matrix[:3, 3] == pytest.approx(frame.xyz, abs=1e-15), frame.name
        assert rotation(frame.quaternion()) == pytest.approx(matrix[:3, :3], abs=1e-12), frame.name
