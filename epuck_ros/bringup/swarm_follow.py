"""What `bringup`'s monitor reads of the swarm topics (epuck_ros/swarm_messages.py), with several robots.

- Which robots a swarm controller drives (`swarm_ports.DeclaredRobots`); such a robot's controller is the node
  publishing `swarm/command` (the readiness `bringup` waits for, as it waits for a robot's `wheel_cmd` publisher).
- Every robot's ground truth of each step, from `swarm/observation`: one message per step instead of one
  `ground_truth` per robot (each a send the simulator makes in its loop).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray

from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw, yaw_from_quaternion
from epuck_ros.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader
from epuck_ros.ros.swarm_ports import DeclaredRobots

_TRUTH = [OBSERVATION_FIELDS.index(field) for field in ('truth_x', 'truth_y', 'truth_yaw')]

Step = Callable[[int, np.ndarray], None]
"""(stamp ns, (N, 3) x, y, yaw): every followed robot's ground truth of one step."""


class SwarmFollower:
    """The swarm controllers' robots, and (once `follow` is called) every robot's ground truth."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._reader = SwarmReader()
        self._declared = DeclaredRobots(node, until_answered=True)   # readiness is decided before the first step

    @property
    def declared(self) -> bool:
        """A swarm controller has declared its robots."""
        return bool(self._declared.robots)

    def controllers(self, robot: str) -> list[tuple[str, str]]:
        """(name, namespace) of the swarm controllers that drive `robot`."""
        return self._declared.controllers(robot)

    def follow(self, robots: Sequence[str], on_step: Step, qos: QoSProfile) -> None:
        """From now on, each step's ground truth of `robots` goes to `on_step`, in one array (a row per robot in the
        order of `robots`, NaN for one the step lacks), the yaw as a `ground_truth` message carries it (a
        quaternion), so the figures are `bag summary`'s."""
        names: tuple[str, ...] = ()
        rows = np.zeros(0, dtype=np.int64)
        """For each robot of the step's message, its row in the array (-1: not followed)."""
        wanted = {name: row for row, name in enumerate(robots)}

        def on_observation(data: bytes) -> None:
            nonlocal names, rows
            read = self._reader.read(data)
            if read is None or read.stamp is None or read.fields != OBSERVATION_FIELDS:
                return
            if read.robots != names:
                names = read.robots
                rows = np.array([wanted.get(name, -1) for name in names], dtype=np.int64)
            truth = read.data[:, _TRUTH]
            truth[:, 2] = [_as_sent(yaw) for yaw in truth[:, 2].tolist()]
            step = np.full((len(robots), 3), np.nan)
            followed = rows >= 0
            step[rows[followed]] = truth[followed]
            on_step(nanoseconds_from_stamp(*read.stamp), step)

        self._node.create_subscription(Float64MultiArray, OBSERVATION_TOPIC, on_observation, qos, raw=True)


def _as_sent(yaw: float) -> float:
    """A yaw as a ground_truth message carries it: through its quaternion."""
    return yaw_from_quaternion(0.0, 0.0, *quaternion_from_yaw(yaw))
