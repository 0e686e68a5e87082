"""The controller's one rclpy node: it answers each simulator step with wheel speeds and gathers the next step.

Webots runs a controller in lockstep: `step()` hands the motor commands over, the world advances, the sensors
are read. Over ROS the same exchange is the step protocol (epuck_ros/lockstep.py): publish `wheel_cmd` naming the
step the controller has seen (`stamp=SEC.NANOSEC` in its layout), then wait until the simulator's next step is
complete here: every topic the script reads — `joint_states` (stamped), `ir_raw` (its label names the step) and
each enabled sense — has its message of one step, newer than the last (`_complete`). Messages are paired by the
step they name, never by arrival order or counts; a step sent again is seen once.
The other senses (camera, ground and light sensors, IMU, ToF) are subscribed when the script enables one (`want`);
a turret device (GPS, Compass, InertialUnit: what the world gives the robot, read from the latched `world`) reads
`ground_truth`, stamped with its step as the senses are (TRUTH). The
simulator computes a sense while its topic has a subscriber, and publishes the current step's reading as soon as it
sees a new one: the answer to the current step waits for that message, so the sense is sure to be read on the next
step, as in Webots (a device enabled before `step()` has its value after it), whenever discovery comes.
Waiting spins this node's executor in the calling (main) thread: a script that does not call `step` leaves
messages queued and the simulator waits for it (lockstep) or, after its `cmd_timeout`, stops the robot.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterType, ParameterValue
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
import numpy as np
from sensor_msgs.msg import Image, Imu, JointState, Range
from std_msgs.msg import Float64MultiArray, Int32MultiArray, String

from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_nanoseconds
from epuck_ros.description import JOINT_NAMES
from epuck_ros.lockstep import Controller
from epuck_ros.model import CAMERA_HEIGHT, CAMERA_WIDTH
from epuck_ros.ros.ack_window import command_qos
from epuck_ros.ros.declaration import Declarer
from epuck_ros.ros.qos import LATCHED, LED_QOS, SCRIPT_READS
from epuck_ros.ros.sense_ports import SENSE_TOPICS
from epuck_ros.ros.serialized import array_bytes, array_values
from epuck_ros.sensors.imu import gyro_values
from epuck_ros.sensors.tof import value_from_range
from epuck_ros.sensors.turret import Truth
from epuck_ros.world import TurretDevice, WorldError, world_from_yaml

QOS = SCRIPT_READS
COMMAND_TOPIC = 'wheel_cmd'
SPIN_PERIOD = 0.1
"""Seconds one wait on the executor lasts at most, so that Ctrl-C and a vanished simulator are noticed."""
KEPT_STEPS = 16
"""Steps a topic's messages are kept for until the others' of the same step come (without lockstep the simulator
may be several steps ahead of a slow controller)."""
PARAMETER_RETRY = 5.0
"""Wall seconds after which the request for the simulator's time_step is sent again."""
DELIVERY_WAIT = 0.9
"""Wall seconds the closing link waits for its readers to acknowledge what it published: within the second a Webots
controller is given to end (robot.KILL_DELAY)."""
ROBOT_CHOICE_GRACE = 3.0
"""Wall seconds the simulator's other robots may be in the graph without ours before `--robot` is refused."""
TRUTH = 'truth'
"""The turret devices' sense: the robot's true state (`sensors.turret.Truth`), the `ground_truth` topic over ROS."""


def _camera_size(values: list[ParameterValue]) -> tuple[int, int]:
    """The simulator's camera_width and camera_height parameters; the e-puck's own size if it has none."""
    if len(values) == 2 and all(v.type == ParameterType.PARAMETER_INTEGER and v.integer_value > 0 for v in values):
        return values[0].integer_value, values[1].integer_value
    return CAMERA_WIDTH, CAMERA_HEIGHT


class LinkError(RuntimeError):
    """The simulator cannot serve this controller (wrong robot name, no time step); the message says why."""


@dataclass(frozen=True)
class StepData:
    """What the simulator says about one step of one robot."""

    time_ns: int
    wheel_angles: tuple[float, float]
    wheel_speeds: tuple[float, float]
    ir_raw: tuple[float, ...]
    senses: dict[str, Any] = field(default_factory=dict)
    """The enabled senses' readings of this step: 'camera' (H, W, 3) uint8, 'ground' (3 values), 'light' (8),
    'imu' ((ax, ay, az) m/s^2, gyro values (3)), 'tof' (its value), TRUTH (a `Truth`, for the turret devices); a sense
    whose first message has not come yet is absent."""


class _Stream:
    """The messages of one topic not yet consumed, by the step (ns) they name."""

    def __init__(self) -> None:
        self.by_step: dict[int, Any] = {}

    def add(self, step: int, value: Any) -> None:
        self.by_step[step] = value
        if len(self.by_step) > KEPT_STEPS:
            del self.by_step[min(self.by_step)]

    def forget_through(self, step: int) -> None:
        """Drop the messages of `step` and before (consumed)."""
        self.by_step = {named: value for named, value in self.by_step.items() if named > step}


class _SenseFeed(_Stream):
    """One enabled sense's messages, by step."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind = kind
        self.started = False
        """A message has come: the simulator reads this sense for our robot."""

    def on_message(self, msg: Any) -> None:
        if self.kind in ('ground', 'light'):
            read = array_values(msg)   # raw bytes: the label names the step
            if read is None or read[1] is None:
                return
            values, stamp = read
            self._add(nanoseconds_from_stamp(*stamp), tuple(values))
            return
        stamp = nanoseconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        if self.kind == 'camera':
            self._add(stamp, np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3))
        elif self.kind == 'tof':   # the value back from the Range's range (sensors/tof.py: `carried`)
            self._add(stamp, float(value_from_range(msg.range)))
        elif self.kind == TRUTH:
            pose, twist = msg.pose.pose, msg.twist.twist
            self._add(stamp, Truth(pose.position.x, pose.position.y, pose.orientation.z, pose.orientation.w,
                                   twist.linear.x, twist.angular.z))
        else:
            rates = (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z)
            self._add(stamp, ((msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z),
                              tuple(gyro_values(np.array(rates), None).tolist())))

    def _add(self, step: int, value: Any) -> None:
        self.started = True
        self.add(step, value)


class SimLink:
    """Publishes `[left, right]` on `<robot>/wheel_cmd`; reads `/clock`, `<robot>/joint_states`, `<robot>/ir_raw`."""

    def __init__(self, node_name: str, robot: str, stop_waiting: Callable[[], bool]) -> None:
        """`robot` '' = the single robot (unprefixed topics); `stop_waiting()` true ends any wait (Ctrl-C)."""
        self.node = Node(node_name)
        self._prefix = f'{robot}/' if robot else ''
        self._robot = robot
        self._stop_waiting = stop_waiting
        self._executor = SingleThreadedExecutor(context=self.node.context)
        self._executor.add_node(self.node)
        # Declared before it is made: lockstep waits for its answers from the first step (epuck_ros/lockstep.py).
        self._declarer = Declarer(self.node)
        self._declarer.declare(Controller.LOCKSTEP, [self.node.resolve_topic_name(self._prefix + COMMAND_TOPIC)])
        self._publisher = self.node.create_publisher(Float64MultiArray, self._prefix + COMMAND_TOPIC, command_qos(1))
        self._joints = _Stream()
        self._ir_raw = _Stream()
        self._consumed_ns = -1
        """The step last handed to the script (ns)."""
        self._subscriptions = [
            self.node.create_subscription(JointState, self._prefix + 'joint_states', self._on_joints, QOS),
            self.node.create_subscription(Float64MultiArray, self._prefix + 'ir_raw', self._on_ir_raw, QOS,
                                          raw=True)]
        self._feeds: dict[str, _SenseFeed] = {}
        self._subscriptions_of_senses: list = []
        self._led_publisher = None
        self._world: list[str] = []
        self._world_subscription = self.node.create_subscription(String, 'world', self._on_world, LATCHED)
        self.turret: tuple[TurretDevice, ...] = ()
        """The devices the simulator's world puts in this robot's turret slot, known once `connect` has returned."""
        self.camera_size = (CAMERA_WIDTH, CAMERA_HEIGHT)
        """(width, height) of the simulator's camera images, known once `connect` has returned: a Camera built
        with it answers getWidth/getHeight right before its first image too (it takes the size of each image)."""

    # --- callbacks --------------------------------------------------------------------------------------------

    def _on_joints(self, msg: JointState) -> None:
        index = {name.rsplit('/', 1)[-1]: i for i, name in enumerate(msg.name)}
        left, right = index.get(JOINT_NAMES[0]), index.get(JOINT_NAMES[1])
        if left is None or right is None:
            return
        self._joints.add(nanoseconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec),
                         ((msg.position[left], msg.position[right]), (msg.velocity[left], msg.velocity[right])))

    def _on_world(self, msg: String) -> None:
        self._world[:] = [msg.data]

    def _on_ir_raw(self, data: bytes) -> None:
        read = array_values(data)   # the label names the step (`serialized`)
        if read is not None and read[1] is not None:
            self._ir_raw.add(nanoseconds_from_stamp(*read[1]), tuple(read[0]))

    # --- connecting -------------------------------------------------------------------------------------------

    def connect(self) -> float | None:
        """Wait for the simulator and this robot's topics; the simulator's time step in seconds (None: stopped)."""
        if not self._wait(self._sim_in_graph, 'the simulator (a node publishing /clock)'):
            return None
        if not self._wait_for_robot():
            return None
        if not self._wait(self._matched, f'the simulator\'s {self._prefix}ir_raw and {self._prefix}joint_states'):
            return None
        if not self._wait(lambda: bool(self._world), 'the simulator\'s world (its latched `world` topic)'):
            return None
        self.turret = self._turret_of(self._world[0])
        self.node.destroy_subscription(self._world_subscription)
        return self._time_step()

    def _turret_of(self, text: str) -> tuple[TurretDevice, ...]:
        """This robot's turret devices in the world the simulator publishes (checked as a world file is)."""
        try:
            world = world_from_yaml(text, 'the simulator\'s world topic')
        except WorldError as error:
            raise LinkError(str(error)) from None
        robots = {robot.name: robot for robot in world.robots}
        robot = robots.get(self._robot) if self._robot else world.robots[0]
        return robot.turret if robot is not None else ()

    def _sim_in_graph(self) -> bool:
        return self.node.count_publishers('/clock') > 0

    def _matched(self) -> bool:
        return self._publisher.get_subscription_count() > 0 and all(
            sub.get_publisher_count() > 0 for sub in self._subscriptions)

    def _robots_in_graph(self) -> list[str]:
        """The robots whose wheel_cmd the simulator subscribes to, as names relative to this node's namespace."""
        namespace = self.node.get_namespace().rstrip('/') + '/'
        robots = []
        for topic, _ in self.node.get_topic_names_and_types():
            if topic.endswith('/' + COMMAND_TOPIC) and topic.startswith(namespace) and \
                    self.node.count_subscribers(topic) > 0:
                robots.append(topic[len(namespace):-len(COMMAND_TOPIC)].rstrip('/'))
        return sorted(robots)

    def _wait_for_robot(self) -> bool:
        """Until the simulator subscribes to our wheel_cmd; LinkError once it clearly serves other robots only."""
        others_since: float | None = None
        while not self._stop_waiting():
            if self._publisher.get_subscription_count() > 0:
                return True
            robots = self._robots_in_graph()
            if robots and self._robot not in robots:  # ours in the graph: only the matching is still to come
                others_since = others_since if others_since is not None else time.monotonic()
                if time.monotonic() - others_since > ROBOT_CHOICE_GRACE:
                    raise LinkError(self._wrong_robot(robots))
            self._executor.spin_once(timeout_sec=SPIN_PERIOD)
        return False

    def _wrong_robot(self, robots: list[str]) -> str:
        if robots == ['']:
            return f'--robot {self._robot}: the simulator has a single robot (its topics carry no robot name); ' \
                   f'leave --robot out'
        names = ', '.join(name for name in robots if name)
        if not self._robot:
            return f'the simulator has several robots ({names}): choose one with --robot NAME'
        return f'--robot {self._robot}: no such robot in the simulator (robots: {names})'

    def _time_step(self) -> float | None:
        """The `time_step` parameter (s) of the node that publishes /clock; None if told to stop first."""
        sources: list[str] = []

        def named() -> bool:
            sources[:] = self._clock_sources()
            return bool(sources)

        if not self._wait(named, 'the name of the node publishing /clock'):
            return None
        client = AsyncParameterClient(self.node, sources[0])
        if not self._wait(client.services_are_ready, f'the parameter services of {sources[0]}'):
            return None
        values = self._parameters(client, ['time_step'], sources[0])
        if values is None:
            return None
        value = values[0].double_value if values else 0.0
        if not value > 0.0:
            raise LinkError(f'{sources[0]} publishes /clock but has no time_step parameter: is it epuck_ros\'s sim?')
        # Asked apart: a node that lacks one of the names asked for answers none of them.
        sizes = self._parameters(client, ['camera_width', 'camera_height'], sources[0])
        if sizes is None:
            return None
        self.camera_size = _camera_size(sizes)
        return value

    def _parameters(self, client: AsyncParameterClient, names: list[str], source: str) -> list | None:
        """The values of `names` on `source` (an empty list if it lacks one); None if told to stop first."""
        future = client.get_parameters(names)
        while not self._wait(future.done, f'{source} to answer', timeout=PARAMETER_RETRY):
            if self._stop_waiting():
                return None
            future = client.get_parameters(names)  # a busy simulator may have lost the request
        return list(future.result().values)

    def _clock_sources(self) -> list[str]:
        """Full names of the nodes publishing /clock (the graph knows an endpoint before its node's name)."""
        return [info.node_namespace.rstrip('/') + '/' + info.node_name
                for info in self.node.get_publishers_info_by_topic('/clock')
                if not info.node_name.startswith('_NODE_NAME_UNKNOWN')]

    def _wait(self, done: Callable[[], bool], what: str, timeout: float = math.inf) -> bool:
        """Spin until `done()`; False if told to stop or after `timeout` s. Says once what it waits for when it
        takes a while."""
        said = False
        started = time.monotonic()
        while not done():
            if self._stop_waiting() or time.monotonic() - started > timeout:
                return False
            if not said and time.monotonic() - started > 2.0:
                print(f'webots_controller: waiting for {what} ...', flush=True)
                said = True
            self._executor.spin_once(timeout_sec=SPIN_PERIOD)
        return True

    # --- stepping ---------------------------------------------------------------------------------------------

    def first_step(self) -> StepData | None:
        """The simulator's current step, once it is complete here (the simulator may be paused until then)."""
        return self._next_step()

    def want(self, kind: str) -> None:
        """From now on gather sense `kind` ('camera', 'ground', 'light', 'imu', 'tof', TRUTH) with every step."""
        if kind in self._feeds:
            return
        feed = self._feeds[kind] = _SenseFeed(kind)
        message = {'camera': Image, 'imu': Imu, 'tof': Range, TRUTH: Odometry}.get(kind, Float64MultiArray)
        topic = 'ground_truth' if kind == TRUTH else SENSE_TOPICS[kind]
        self._subscriptions_of_senses.append(self.node.create_subscription(
            message, self._prefix + topic, feed.on_message, QOS, raw=message is Float64MultiArray))

    def publish_leds(self, values: list[int]) -> None:
        """The ten LED values the script set (latched: a view started later still draws them)."""
        if self._led_publisher is None:
            self._led_publisher = self.node.create_publisher(Int32MultiArray, self._prefix + 'leds', LED_QOS)
        self._led_publisher.publish(Int32MultiArray(data=[int(v) for v in values]))

    def answer_and_wait(self, left: float, right: float) -> StepData | None:
        """Send the wheel speeds for the step last returned, naming it, then wait for the next one (None: stop or sim
        gone). A sense enabled since the last answer is first heard from: the simulator then reads it next step."""
        for feed in self._feeds.values():
            if not feed.started and not self._wait(lambda: feed.started, f'the simulator\'s {feed.kind} readings'):
                return None
        self._publisher.publish(array_bytes((float(left), float(right)), stamp_from_nanoseconds(self._consumed_ns)))
        return self._next_step()

    def _complete(self) -> int | None:
        """The newest step, newer than the last one consumed, of which every topic read has its message."""
        feeds = [feed for feed in self._feeds.values() if feed.started]
        for step in sorted(self._joints.by_step, reverse=True):
            if step > self._consumed_ns and step in self._ir_raw.by_step and \
                    all(step in feed.by_step for feed in feeds):
                return step
        return None

    def _next_step(self) -> StepData | None:
        last_check = time.monotonic()
        while (step := self._complete()) is None:
            if self._stop_waiting():
                return None
            self._executor.spin_once(timeout_sec=SPIN_PERIOD)
            if time.monotonic() - last_check > SPIN_PERIOD:
                last_check = time.monotonic()
                if not self._sim_in_graph():
                    print('webots_controller: the simulator is gone', flush=True)
                    return None
        self._consumed_ns = step
        angles, speeds = self._joints.by_step[step]
        senses = {kind: feed.by_step[step] for kind, feed in self._feeds.items() if step in feed.by_step}
        data = StepData(step, angles, speeds, self._ir_raw.by_step[step], senses)
        for stream in (self._joints, self._ir_raw, *self._feeds.values()):
            stream.forget_through(step)
        return data

    def close(self) -> None:
        """The node goes, once every reader has what it published (at most DELIVERY_WAIT): a reader that fell behind
        (a recorder, with `bringup` stopping the controller first) lost the last answers and LEDs with the process."""
        deadline = time.monotonic() + DELIVERY_WAIT
        self._declarer.goodbye([self._publisher.topic_name])   # a lockstep simulator goes on without it
        for publisher in (self._publisher, self._led_publisher, self._declarer.publisher):
            if publisher is not None and \
                    not publisher.wait_for_all_acked(Duration(seconds=max(0.0, deadline - time.monotonic()))):
                print(f'webots_controller: a reader of {publisher.topic_name} had not taken everything within '
                      f'{DELIVERY_WAIT:g} s: a recording may miss the last messages', flush=True)
        self._executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()
