"""The simulator's swarm ports: every robot's step in one message out, many robots' answers in one message in.

`swarm/observation` (published only while someone reads it) carries each step's odometry, ground truth, wheels and
raw IR of every robot; `swarm/command` takes a controller's answers for the robots it names
(`swarm_messages`). Each robot named in a command is answered by the rule of every robot's `wheel_cmd`
(`SimNode._on_swarm_command`: paired with the step by the name it carries, then `Lockstep.answer` per robot), so a
swarm's run is step for step the one its per-robot topics would give. The per-robot topics stay, for everyone who
reads or drives a robot by them.

Lockstep membership: a swarm controller declares the robots it drives before its first answer (a command with no
fields, `swarm_messages`), on a transient-local topic, so the simulator learns them as soon as it matches the
controller, however late: they are driven from then on (`driven`, while the controller is connected both ways), and
the simulator takes it as a declaration in lockstep of each (`SimNode._on_declare`): waited for however long the first
answer takes.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray

from epuck_ros.conversions import nanoseconds_from_stamp
from epuck_ros.ros.qos import COMMAND_READER_QOS
from epuck_ros.ros.robot_ports import WARN_PERIOD, quiet_publisher
from epuck_ros.swarm_messages import (COMMAND_FIELDS, COMMAND_TOPIC, OBSERVATION_FIELDS, OBSERVATION_TOPIC,
                                      SwarmLayout, SwarmReader, observation_values)
from epuck_ros.simulation import Simulation

CommandsHandler = Callable[[np.ndarray, np.ndarray, 'int | None'], None]
"""(robots (their indices, each once), their wheel speeds (robots x 2, rad/s), the step they answer in ns or None):
what the node does with a swarm command."""


class SwarmPorts:
    """`swarm/observation` out and `swarm/command` in, for the robots `names` (the simulation's, in its order)."""

    def __init__(self, node: Node, names: Sequence[str], stream_qos: QoSProfile, on_commands: CommandsHandler,
                 on_declare: Callable[[list[int]], None]) -> None:
        """`on_commands(robots, speeds, named)`: the node's handler of these robots' wheel speeds (rad/s, one row
        each), naming step `named` (ns; None: none); `on_declare(robots)`: a controller declared it answers these
        robots' steps by name."""
        self._index = {name: index for index, name in enumerate(names)}
        self._on_commands, self._on_declare = on_commands, on_declare
        self._logger = node.get_logger()
        self._layout = SwarmLayout(names, OBSERVATION_FIELDS)
        self._values = np.zeros((len(names), len(OBSERVATION_FIELDS)))
        self._publisher = quiet_publisher(node, Float64MultiArray, OBSERVATION_TOPIC, stream_qos)
        self.stream_publishers = [self._publisher]
        self._subscription = node.create_subscription(Float64MultiArray, COMMAND_TOPIC, self._on_message,
                                                      COMMAND_READER_QOS, raw=True)
        self.topic = self._subscription.topic_name
        self._reader = SwarmReader()
        self._rows: tuple[tuple[str, ...], list[int], np.ndarray] = ((), [], np.zeros(0, dtype=np.intp))
        """The robots of the last command's layout and their rows in the simulation (as a list and as an array)."""
        self._declared: frozenset[int] = frozenset()
        """Robots some swarm controller named (declared or answered for): driven while the topic has a publisher."""

    def driven(self) -> frozenset[int]:
        """The robots a swarm controller drives now (lockstep waits for their answers): those it named, once it is
        connected both ways (the observation has a reader too: a first step published before this simulator matched
        that reader would be lost, and answered only once re-sent, a second later)."""
        if not self._subscription.get_publisher_count():
            self._declared = frozenset()   # its controller left: a new one declares its own
        return self._declared if self._publisher.get_subscription_count() else frozenset()

    def publish(self, sim: Simulation, stamp: tuple[int, int]) -> None:
        """Every robot's step in one message, if someone reads it (`stamp`: the step's (sec, nanosec))."""
        if not self._publisher.get_subscription_count():
            return
        self._publisher.publish(self._layout.to_bytes(observation_values(sim, self._values), stamp))

    def _on_message(self, data: bytes) -> None:
        read = self._reader.read(data)
        if read is None or read.fields not in (COMMAND_FIELDS, ()):
            got = 'bytes that are no swarm array' if read is None else f'fields {",".join(read.fields)}'
            self._warn(f'data must be a swarm array of fields {",".join(COMMAND_FIELDS)} (or none: a '
                       f'declaration), got {got}')
            return
        if not self._rows_of(read.robots):
            return
        _, rows, indices = self._rows
        if not self._declared.issuperset(rows):
            self._declared = self._declared | frozenset(rows)
        if not read.fields:
            self._on_declare(rows)
            return
        self._on_commands(indices, read.data, None if read.stamp is None else nanoseconds_from_stamp(*read.stamp))

    def _rows_of(self, robots: tuple[str, ...]) -> bool:
        """Whether `robots` are the simulation's, each once (`_rows` then holds their rows, kept for the next
        message of the same robots); if not, said."""
        if robots == self._rows[0]:
            return True
        unknown = [name for name in robots if name not in self._index]
        if unknown or len(set(robots)) != len(robots):
            self._warn(f'no robot {unknown[0]!r} in this simulation' if unknown else 'a robot is named twice')
            return False
        rows = [self._index[name] for name in robots]
        self._rows = (robots, rows, np.array(rows, dtype=np.intp))
        return True

    def _warn(self, why: str) -> None:
        self._logger.warning(f'{self.topic} refused: {why}', throttle_duration_sec=WARN_PERIOD)


class DeclaredRobots:
    """Which robots the swarm controllers on the domain drive, as a third party learns it (bringup's monitor, the
    `epuck_sim` fixture): from their declarations on `swarm/command` (transient local: they arrive however late this
    node matches the controller), and the robots every later command names. `until_answered`: stop reading the
    commands at the first answer to a step (the run is under way; one reader fewer for the controller to send each
    step to: the controller's send took 0.7 ms a step with bringup's monitor reading them, 0.15 ms without)."""

    def __init__(self, node: Node, until_answered: bool = False) -> None:
        self._node = node
        self._reader = SwarmReader()
        self._until_answered = until_answered
        self.robots: frozenset[str] = frozenset()
        self._publishers: tuple[frozenset[str], list[tuple[str, str]]] = (self.robots, [])
        """The robots named when the graph was last asked, and the publishers it showed."""
        self._subscription = node.create_subscription(Float64MultiArray, COMMAND_TOPIC, self._on_command,
                                                      COMMAND_READER_QOS, raw=True)

    def _on_command(self, data: bytes) -> None:
        read = self._reader.read(data)
        if read is None:
            return
        if not self.robots.issuperset(read.robots):
            self.robots = self.robots | frozenset(read.robots)
        if read.stamp is not None and self._until_answered and self._subscription is not None:
            self._node.destroy_subscription(self._subscription)
            self._subscription = None

    def controllers(self, robot: str) -> list[tuple[str, str]]:
        """(name, namespace) of the nodes publishing `swarm/command`, if one of them named `robot`. The graph is
        asked once for all the robots named so far (each look reads the whole graph: a swarm's thousands of
        topics), again only once more robots are named."""
        if robot not in self.robots:
            return []
        robots, found = self._publishers
        if robots is not self.robots or not found:
            found = [(info.node_name, info.node_namespace) for info in
                     self._node.get_publishers_info_by_topic(self._node.resolve_topic_name(COMMAND_TOPIC))]
            self._publishers = (self.robots, found)
        return found
