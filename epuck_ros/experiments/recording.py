"""A headless trial written as the rosbag2 MCAP bag `bringup --record` writes of the same run.

The simulator's side is made by the simulator's own code: its robots' ports (`RobotPorts`, `SensePorts`), its TF
(`TfPorts`), its world (`publish_world`) and its /clock, each bound to a `BagNode`, whose publishers write into the
bag instead of sending over DDS. So a headless bag has the topics, types, bytes and frames of a recorded run by
construction: robot_description, /tf_static and /tf, odom, ground_truth, proximity, joint_states, ir_raw and
collisions per robot, the senses a controller read while it read them (as the simulator publishes them: from the step
after it asked) and the e-puck interface's topics of those senses (`InterfacePorts`: ls0..ls7 with the light,
image_raw and camera_info with the camera), world, world_markers and /clock; each topic offered with the QoS a
recorder reads from the graph.
A sense is published from the step its controller asked for it on, as the simulator publishes a newly wanted sense's
current step at once, and `lockstep_status` says the run held (a headless trial is lockstep, always).
The controllers' side as their nodes publish it: each robot's `wheel_cmd`, one answer per step before the last (the
answer to the last step drives nothing; a behaviour's node ends with a stop), its array naming the step it answers
(`layout.dim[0].label` = `conversions.stamp_label`), and a script's `leds` whenever it changes them.
What only a run over ROS has is not in it: /rosout, /parameter_events, /simulators (the processes' log lines,
bringup's resume and pause, the simulators' announcements). Log times are the steps' stamps.
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, Int32MultiArray

from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.writer import BagWriter
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_seconds
from epuck_ros.integrity import HELD
from epuck_ros.model import RobotModel
from epuck_ros.ros.ack_window import command_qos, history_steps
from epuck_ros.ros.interface_ports import INTERFACE_TOPICS, InterfacePorts
from epuck_ros.ros.lockstep_report import LockstepReport
from epuck_ros.ros.qos import LATCHED, LED_QOS, clock_kept, step_stream
from epuck_ros.ros.robot_ports import WORLD_FRAME, RobotPorts, topic_prefix
from epuck_ros.ros.sense_ports import ON_DEMAND_TOPICS, SensePorts
from epuck_ros.ros.serialized import Patch, array_bytes, exact_cdr
from epuck_ros.swarm_messages import (COMMAND_FIELDS, OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmLayout,
                                      observation_values)
from epuck_ros.swarm_messages import COMMAND_TOPIC as SWARM_COMMAND_TOPIC
from epuck_ros.nodes.sim_node import publish_world
from epuck_ros.ros.tf_ports import TfPorts
from epuck_ros.simulation import Simulation
from epuck_ros.webots.link import COMMAND_TOPIC
from epuck_ros.world import World

READ = dict.fromkeys(ON_DEMAND_TOPICS, True)
"""Every sense topic has a reader (the recorder): the senses the simulation computes are published."""
INTERFACE_READ = dict.fromkeys(INTERFACE_TOPICS, True)
"""The same for the e-puck interface's topics (ros/interface_ports.py)."""


def offered(qos: QoSProfile) -> QosProfile:
    """A publisher's QoS as a recorder reads it from the graph: Fast DDS tells a remote publisher's reliability and
    durability, not its history or depth (`history: unknown`, `depth: 0` in every recorded bag)."""
    return QosProfile(history='unknown', depth=0, reliability=qos.reliability.name.lower(),
                      durability=qos.durability.name.lower())


class _BagPublisher:
    """What a port's publisher does, into the bag: messages or their CDR bytes, at the node's current step."""

    def __init__(self, node: BagNode, msg_type: type, topic: str, qos: QoSProfile) -> None:
        self._node, self.topic_name = node, node.resolve_topic_name(topic)
        self._type = f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'
        self._qos = [offered(qos)]

    def publish(self, msg: Any) -> None:
        self._node.write(self.topic_name, self._type, self._qos, msg if isinstance(msg, bytes) else exact_cdr(msg))

    def get_subscription_count(self) -> int:
        """The recorder reads every topic."""
        return 1


class _NoSubscription:
    """A port's command subscription: nothing publishes to it here."""

    def get_publisher_count(self) -> int:
        return 0


class BagNode:
    """Stands for the simulator's node to its ports: their publishers write into `bag`, each message logged at the
    current step's stamp (`now_ns`); what they publish before the first step waits for it, as a recorder holds what
    comes before the first /clock. A topic enters the bag with its first message."""

    def __init__(self, bag: BagWriter) -> None:
        self._bag = bag
        self.now_ns: int | None = None
        self._held: list[tuple[str, bytes]] = []

    def create_publisher(self, msg_type: type, topic: str, qos: QoSProfile, **_: Any) -> _BagPublisher:
        return _BagPublisher(self, msg_type, topic, qos)

    def create_subscription(self, *_: Any, **__: Any) -> _NoSubscription:
        return _NoSubscription()

    def get_logger(self) -> logging.Logger:
        return logging.getLogger('epuck_ros.recording')

    def resolve_topic_name(self, topic: str) -> str:
        return topic if topic.startswith('/') else '/' + topic

    def write(self, topic: str, type_name: str, qos: list[QosProfile], data: bytes) -> None:
        if topic not in self._bag.topics:
            self._bag.add_topic(topic, type_name, qos)
        if self.now_ns is None:
            self._held.append((topic, data))
        else:
            self._bag.write(topic, data, self.now_ns)

    def step(self, stamp: tuple[int, int]) -> None:
        """From now on messages are of the step stamped `stamp`; those held are written with the first."""
        self.now_ns = nanoseconds_from_stamp(*stamp)
        for topic, data in self._held:
            self._bag.write(topic, data, self.now_ns)
        self._held.clear()


class TrialRecorder:
    """`step(sim)` after every step the simulator publishes (trial.run's), `answered` for each controller's answer,
    `leds` when a script sets them, `stop` when behaviours end; `close()` at the end. Thread-safe: a script answers
    from its own thread."""

    def __init__(self, path: Path, world: World, controller_robots: int, model: RobotModel = RobotModel()) -> None:
        """`controller_robots`: how many robots each controller drives from one process over ROS (a script: 1, one
        `webots_controller` per robot; a behaviour: every robot, `--robots all`), for the QoS its `wheel_cmd` has;
        several: one swarm controller, which answers on `swarm/command` (and reads `swarm/observation`)."""
        self._bag = BagWriter(path)
        self._command_qos = command_qos(controller_robots)
        self._swarm: _SwarmRecord | None = None
        self._one_swarm_controller = controller_robots > 1
        self._node = BagNode(self._bag)
        self._world, self._model = world, model
        self._lock = threading.Lock()
        self._ports: list[RobotPorts] = []
        self._senses: list[SensePorts] = []
        self._controllers: list[tuple[_BagPublisher, _BagPublisher]] = []
        self._collisions: list[int] = []
        self._stamp = (0, 0)

    def _start(self, sim: Simulation) -> None:
        """The simulator's ports, as the sim node makes them (their latched messages go out at once)."""
        node, several = self._node, len(sim.names) > 1
        stream = step_stream(history_steps(len(sim.names)))
        self._ports = [RobotPorts(node, index, name, several, stream, LATCHED, lambda *_: None, model=self._model)
                       for index, name in enumerate(sim.names)]
        self._senses = [SensePorts(node, index, name, several, stream, sim) for index, name in enumerate(sim.names)]
        self._interface = [InterfacePorts(node, index, name, several, stream, sim, model=self._model)
                           for index, name in enumerate(sim.names)]
        self._tf = TfPorts(node, self._ports, sim, several, stream, LATCHED, WORLD_FRAME, self._model)
        publish_world(node, self._world, '')
        LockstepReport(node, sim.names, HELD, 0.0, lambda: sim.time)
        self._clock = node.create_publisher(Clock, '/clock', clock_kept(stream.depth))
        self._clock_message = Patch(Clock(), [('clock.sec', 'i'), ('clock.nanosec', 'I')])   # as the sim node's
        self._controllers = [(node.create_publisher(Float64MultiArray, topic_prefix(name, several) + COMMAND_TOPIC,
                                                    self._command_qos),
                              node.create_publisher(Int32MultiArray, topic_prefix(name, several) + 'leds', LED_QOS))
                             for name in sim.names]
        self._collisions = [0] * len(sim.names)
        if self._one_swarm_controller:
            self._swarm = _SwarmRecord(node, sim.names, stream, self._command_qos)

    def step(self, sim: Simulation) -> None:
        """The step just taken, published as the sim node publishes it; /clock last."""
        with self._lock:
            if not self._ports:
                self._start(sim)
            if self._swarm is not None:
                self._swarm.answers_of(self._stamp)   # the last step's, before this one's messages
            last, self._stamp = self._stamp, stamp_from_seconds(sim.time)
            stamp = self._stamp
            self._node.step(stamp)
            for ports, senses, interface in zip(self._ports, self._senses, self._interface):
                ports.publish(sim, stamp)
                _follow(senses, sim)
                _follow_interface(interface, sim)
                # what changed since the last step, said with this one (as the sim node)
                senses.announce(last, interface.published_topics)
                if senses.publishing:
                    senses.publish(sim, stamp)
                if interface.publishing:
                    interface.publish(sim, stamp)
            if self._swarm is not None:
                self._swarm.observation(sim, stamp)
            self._tf.publish(sim, stamp)
            for robot, count in enumerate(sim.collisions.tolist()):
                if count != self._collisions[robot]:
                    self._collisions[robot] = count
                    self._ports[robot].publish_collisions(count)
            self._clock.publish(self._clock_message.bytes(stamp))

    def sense_wanted(self, robot: int, kind: str, sim: Simulation) -> None:
        """Robot `robot`'s controller asked for sense `kind` (read at once): its message of the current step."""
        with self._lock:
            senses = self._senses[robot]
            _follow(senses, sim)
            senses.publish(sim, self._stamp, [kind])
            interface = self._interface[robot]
            interface.publish(sim, self._stamp, _follow_interface(interface, sim))

    def answered(self, robot: int, left: float, right: float) -> None:
        """Robot `robot`'s controller answered the current step with these wheel speeds (rad/s), naming it."""
        with self._lock:
            if self._swarm is not None:
                self._swarm.answered(robot, left, right)
            else:
                self._controllers[robot][0].publish(array_bytes((float(left), float(right)), self._stamp))

    def leds(self, robot: int, values: Sequence[int]) -> None:
        """A script set its LEDs (the ten values, as the Webots shim publishes them)."""
        with self._lock:
            self._controllers[robot][1].publish(Int32MultiArray(data=[int(value) for value in values]))

    def stop(self) -> None:
        """The behaviours' nodes end: each commands a zero wheel speed (unnamed: it answers no step)."""
        with self._lock:
            if self._swarm is not None:
                self._swarm.stop()
                return
            for command, _ in self._controllers:
                command.publish(array_bytes((0.0, 0.0)))

    def close(self) -> None:
        self._bag.close()


class _SwarmRecord:
    """The swarm topics of a run whose robots one swarm controller drives (`behaviour_nodes.SwarmController`), as
    the recorder gets them over ROS: the controller's declaration, then each step's `swarm/observation` and its one
    `swarm/command` with every robot's answer, and at the end its unnamed stop."""

    def __init__(self, node: BagNode, names: Sequence[str], stream: QoSProfile, commands_qos: QoSProfile) -> None:
        self._observations = node.create_publisher(Float64MultiArray, OBSERVATION_TOPIC, stream)
        self._layout = SwarmLayout(names, OBSERVATION_FIELDS)
        self._commands = node.create_publisher(Float64MultiArray, SWARM_COMMAND_TOPIC, commands_qos)
        self._command_layout = SwarmLayout(names, COMMAND_FIELDS)
        self._speeds = np.zeros((len(names), len(COMMAND_FIELDS)))
        self._answered = False
        self._commands.publish(SwarmLayout(names, ()).to_bytes(np.zeros((len(names), 0)), None))

    def observation(self, sim: Simulation, stamp: tuple[int, int]) -> None:
        self._observations.publish(self._layout.to_bytes(observation_values(sim), stamp))

    def answered(self, robot: int, left: float, right: float) -> None:
        self._speeds[robot] = left, right
        self._answered = True

    def answers_of(self, stamp: tuple[int, int]) -> None:
        """The answers given since the last step, in one command naming it (`stamp`)."""
        if self._answered:
            self._commands.publish(self._command_layout.to_bytes(self._speeds, stamp))
            self._answered = False

    def stop(self) -> None:
        self._commands.publish(self._command_layout.to_bytes(np.zeros_like(self._speeds), None))


def _follow(senses: SensePorts, sim: Simulation) -> None:
    """The robot's sense topics publish what the simulation computes for it (the recorder reads them all)."""
    senses.follow({kind: bool(wanted[senses.index]) for kind, wanted in sim.senses.wanted.items()}, READ)


def _follow_interface(interface: InterfacePorts, sim: Simulation) -> list[str]:
    """The robot's e-puck interface topics publish what the simulation computes for it (the recorder reads them
    all); the kinds newly published."""
    return interface.follow(lambda kind: bool(sim.senses.wanted[kind][interface.index]), INTERFACE_READ)
