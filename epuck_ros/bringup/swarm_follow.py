"""What `bringup`'s monitor reads of the swarm topics (nodes/swarm_messages.py), with several robots.

- Which robots a swarm controller drives (`swarm_ports.DeclaredRobots`); such a robot's controller is the node
  publishing `swarm/command` (the readiness `bringup` waits for, as it waits for a robot's `wheel_cmd` publisher).
- Every robot's ground truth of each step, from `swarm/observation`: one message per step instead of one
  `ground_truth` per robot (each a send the simulator makes in its loop).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray

from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw, yaw_from_quaternion
from epuck_ros.nodes.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader
from epuck_ros.nodes.swarm_ports import DeclaredRobots

_TRUTH = [OBSERVATION_FIELDS.index(field) for field in ('truth_x', 'truth_y', 'truth_yaw')]

Sample = Callable[[int, float, float, float], None]
"""(stamp ns, x, y, yaw): one robot's ground-truth sample."""


class SwarmFollower:
    """The swarm controllers' robots, and (once `follow` is called) every robot's ground truth."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._reader = SwarmReader()
        self._declared = DeclaredRobots(node, until_answered=True)   # readiness is decided before the first step
        self._samples: list[Sample | None] = []

    def controllers(self, robot: str) -> list[tuple[str, str]]:
        """(name, namespace) of the swarm controllers that drive `robot`."""
        return self._declared.controllers(robot)

    def follow(self, robots: Mapping[str, Sample], qos: QoSProfile) -> None:
        """From now on, each step's ground truth of the robots named in `robots` goes to their `Sample`: the yaw as
        a `ground_truth` message carries it (a quaternion), so the figures are `bag summary`'s."""
        names: tuple[str, ...] = ()

        def on_observation(data: bytes) -> None:
            nonlocal names
            read = self._reader.read(data)
            if read is None or read.stamp is None or read.fields != OBSERVATION_FIELDS:
                return
            if read.robots != names:
                names = read.robots
                self._samples = [robots.get(name) for name in names]
            stamp = nanoseconds_from_stamp(*read.stamp)
            for sample, (x, y, yaw) in zip(self._samples, read.data[:, _TRUTH].tolist()):
                if sample is not None:
                    sample(stamp, x, y, yaw_from_quaternion(0.0, 0.0, *quaternion_from_yaw(yaw)))

        self._node.create_subscription(Float64MultiArray, OBSERVATION_TOPIC, on_observation, qos, raw=True)
