"""A headless trial written as a rosbag2 MCAP bag: the messages the simulator would publish for each step, with the
same topics, types, frame ids and stamps, serialised by rosbags' typestore and written by `bag.writer.BagWriter`,
so `bag` (summary, plot, play) and rosbags' AnyReader read it as they read a recorded run.

What the simulator node publishes is fixed in `nodes/robot_ports.py` (per robot: odom, ground_truth, 8 Range on
proximity, joint_states, ir_raw, collisions) and `nodes/sim_node.py` (/clock last, the latched world and
world_markers); the constants are taken from there. The controllers' own topics (wheel_cmd) are not simulated
here, so a headless bag has none.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml
from rosbags.typesys import Stores, get_typestore

from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.writer import BagWriter
from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw, stamp_from_seconds, stamp_label
from epuck_ros.markers import world_markers
from epuck_ros.model import SENSOR_NAMES, RobotModel
from epuck_ros.nodes.robot_ports import (JOINT_NAMES, POSE_COVARIANCE, TWIST_COVARIANCE, WORLD_FRAME, frame_prefix,
                                         topic_prefix)
from epuck_ros.nodes.serialized import exact_cdr
from epuck_ros.simulation import Simulation
from epuck_ros.world import World

TYPES = get_typestore(Stores.ROS2_JAZZY)
STREAM = [QosProfile(depth=10)]
LATCHED = [QosProfile(depth=1, durability='transient_local')]
INFRARED = 1
"""sensor_msgs/Range's INFRARED."""


def _t(name: str) -> Any:
    return TYPES.types[name]


def _diagonal(values: list[float]) -> np.ndarray:
    matrix = np.zeros(36)
    matrix[::7][:len(values)] = values
    return matrix


class TrialRecorder:
    """`step(sim)` after every step the simulator publishes (trial.run's `each_step`); `close()` at the end."""

    def __init__(self, path: Path, world: World, model: RobotModel = RobotModel()) -> None:
        self._bag = BagWriter(path)
        self._world, self._model = world, model
        self._several = len(world.robots) > 1
        self._collisions: list[int] | None = None
        self._started = False

    def _topic(self, name: str, type_name: str, qos: list[QosProfile] = STREAM) -> None:
        self._bag.add_topic(name, type_name, qos)

    def _write(self, topic: str, message: Any, stamp: int) -> None:
        self._bag.write(topic, bytes(TYPES.serialize_cdr(message, message.__msgtype__)), stamp)

    def _start(self, sim: Simulation, stamp: int) -> None:
        self._started = True
        self._topic('/world', 'std_msgs/msg/String', LATCHED)
        self._write('/world', _t('std_msgs/msg/String')(data=yaml.safe_dump(self._world.to_dict(), sort_keys=False)),
                    stamp)
        self._topic('/world_markers', 'visualization_msgs/msg/MarkerArray', LATCHED)
        self._bag.write('/world_markers', exact_cdr(world_markers(self._world, WORLD_FRAME)), stamp)
        self._topic('/clock', 'rosgraph_msgs/msg/Clock')
        for name in sim.names:
            topics = topic_prefix(name, self._several)
            for topic, type_name in (('odom', 'nav_msgs/msg/Odometry'), ('ground_truth', 'nav_msgs/msg/Odometry'),
                                     ('proximity', 'sensor_msgs/msg/Range'),
                                     ('joint_states', 'sensor_msgs/msg/JointState'),
                                     ('ir_raw', 'std_msgs/msg/Float64MultiArray')):
                self._topic('/' + topics + topic, type_name)
            self._topic('/' + topics + 'collisions', 'std_msgs/msg/UInt32', LATCHED)
        self._collisions = [-1] * len(sim.names)

    def step(self, sim: Simulation) -> None:
        sec, nanosec = stamp_from_seconds(sim.time)
        stamp = nanoseconds_from_stamp(sec, nanosec)
        if not self._started:
            self._start(sim, stamp)
        time = _t('builtin_interfaces/msg/Time')(sec=sec, nanosec=nanosec)
        for robot, name in enumerate(sim.names):
            topics, frames = topic_prefix(name, self._several), frame_prefix(name, self._several)
            self._write('/' + topics + 'odom', _odometry(time, frames + 'odom', frames + 'base_link',
                                                         sim.odom_pose[robot], sim.odom_twist[robot], True), stamp)
            self._write('/' + topics + 'ground_truth', _odometry(time, WORLD_FRAME, frames + 'base_link',
                                                                 sim.true_pose[robot], sim.true_twist[robot], False),
                        stamp)
            data = sim.ir_raw[robot].astype(np.float64)
            step = _t('std_msgs/msg/MultiArrayDimension')(label=stamp_label(sec, nanosec), size=len(data),
                                                          stride=len(data))   # names its step, as the sim's
            self._write('/' + topics + 'ir_raw', _t('std_msgs/msg/Float64MultiArray')(
                layout=_t('std_msgs/msg/MultiArrayLayout')(dim=[step], data_offset=0), data=data), stamp)
            for sensor, value in zip(SENSOR_NAMES, sim.ir_range[robot].tolist()):
                self._write('/' + topics + 'proximity', _t('sensor_msgs/msg/Range')(
                    header=_header(time, frames + sensor), radiation_type=INFRARED,
                    field_of_view=self._model.ir_aperture, min_range=0.0, max_range=self._model.ir_range,
                    range=value, variance=0.0), stamp)
            self._write('/' + topics + 'joint_states', _t('sensor_msgs/msg/JointState')(
                header=_header(time, ''), name=list(JOINT_NAMES),
                position=sim.wheel_angles[robot].astype(np.float64),
                velocity=sim.wheel_speeds[robot].astype(np.float64), effort=np.zeros(0)), stamp)
            count = int(sim.collisions[robot])
            if count != self._collisions[robot]:
                self._collisions[robot] = count
                self._write('/' + topics + 'collisions', _t('std_msgs/msg/UInt32')(data=count), stamp)
        self._write('/clock', _t('rosgraph_msgs/msg/Clock')(clock=time), stamp)

    def close(self) -> None:
        self._bag.close()


def _header(time: Any, frame_id: str) -> Any:
    return _t('std_msgs/msg/Header')(stamp=time, frame_id=frame_id)


def _odometry(time: Any, frame_id: str, child: str, pose: np.ndarray, twist: np.ndarray, covariances: bool) -> Any:
    """As robot_ports publishes it: a planar pose's quaternion is a rotation about z; odometry has covariances."""
    x, y, yaw = pose.tolist()
    geometry = 'geometry_msgs/msg/'
    point = _t(geometry + 'Point')(x=x, y=y, z=0.0)
    z, w = quaternion_from_yaw(yaw)
    orientation = _t(geometry + 'Quaternion')(x=0.0, y=0.0, z=z, w=w)
    linear, angular = twist.tolist()
    velocity = _t(geometry + 'Twist')(linear=_t(geometry + 'Vector3')(x=linear, y=0.0, z=0.0),
                                      angular=_t(geometry + 'Vector3')(x=0.0, y=0.0, z=angular))
    return _t('nav_msgs/msg/Odometry')(
        header=_header(time, frame_id), child_frame_id=child,
        pose=_t(geometry + 'PoseWithCovariance')(pose=_t(geometry + 'Pose')(position=point, orientation=orientation),
                                                 covariance=_diagonal(POSE_COVARIANCE if covariances else [])),
        twist=_t(geometry + 'TwistWithCovariance')(twist=velocity,
                                                   covariance=_diagonal(TWIST_COVARIANCE if covariances else [])))
