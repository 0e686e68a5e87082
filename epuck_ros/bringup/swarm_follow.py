"""What `bringup`'s monitor reads of the swarm topics (nodes/swarm_messages.py), with several robots.

- Which robots a swarm controller drives: its declaration on `swarm/command` (transient local, so it arrives
  however late this node matches the controller) names them; such a robot's controller is the node publishing
  `swarm/command` (the readiness `bringup` waits for, as it waits for a robot's `wheel_cmd` publisher).
- Every robot's ground truth of each step, from `swarm/observation`: one message per step instead of one
  `ground_truth` per robot (each a send the simulator makes in its loop).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray

from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw, yaw_from_quaternion
from epuck_ros.nodes.swarm_messages import COMMAND_TOPIC, OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader
from epuck_ros.nodes.swarm_ports import COMMAND_READER_QOS

_TRUTH = [OBSERVATION_FIELDS.index(field) for field in ('truth_x', 'truth_y', 'truth_yaw')]

Sample = Callable[[int, float, float, float], None]
"""(stamp ns, x, y, yaw): one robot's ground-truth sample."""


class SwarmFollower:
    """The swarm controllers' robots, and (once `follow` is called) every robot's ground truth."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._reader = SwarmReader()
        self.driven: frozenset[str] = frozenset()
        """Robots a swarm controller named (declared, or answered for)."""
        self._commands = node.create_subscription(Float64MultiArray, COMMAND_TOPIC, self._on_command,
                                                  COMMAND_READER_QOS, raw=True)
        self._samples: list[Sample | None] = []

    def _on_command(self, data: bytes) -> None:
        read = self._reader.read(data)
        if read is None:
            return
        if not self.driven.issuperset(read.robots):
            self.driven = self.driven | frozenset(read.robots)
        if read.stamp is not None and self._commands is not None:
            # An answer: the run is under way, its readiness was decided before the resume. One reader fewer for
            # the controller to send each step to.
            self._node.destroy_subscription(self._commands)
            self._commands = None

    def controllers(self, robot: str) -> list[tuple[str, str]]:
        """(name, namespace) of the nodes publishing `swarm/command`, if one of them named `robot`."""
        if robot not in self.driven:
            return []
        return [(info.node_name, info.node_namespace)
                for info in self._node.get_publishers_info_by_topic(self._node.resolve_topic_name(COMMAND_TOPIC))]

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
