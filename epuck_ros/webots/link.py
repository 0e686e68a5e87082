"""The controller's one rclpy node: it answers each simulator step with wheel speeds and gathers the next step.

Webots runs a controller in lockstep: `step()` hands the motor commands over, the world advances, the sensors
are read. Over ROS the same exchange is: publish `wheel_cmd` (the answer to the step the controller has seen),
then wait until the simulator's next step is complete here: its `/clock`, its `joint_states` (stamped with
that time) and its `ir_raw` (unstamped: matched by count, see `_complete`). With the simulator in lockstep
nothing of a later step exists before the answer, so every reading belongs to the step asked for.
The other senses (camera, ground and light sensors, IMU) are subscribed when the script enables one (`want`):
the simulator computes a sense while its topic has a subscriber, so from its first message on a step is complete
only with that sense's reading of the same step too (stamped ones by stamp, the arrays by count as ir_raw).
Waiting spins this node's executor in the calling (main) thread: a script that does not call `step` leaves
messages queued and the simulator, after its `cmd_timeout`, stops the robot.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rcl_interfaces.msg import ParameterType, ParameterValue
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
import numpy as np
from sensor_msgs.msg import Image, Imu, JointState
from std_msgs.msg import Float64MultiArray, Int32MultiArray

from epuck_ros.conversions import nanoseconds_from_stamp
from epuck_ros.model import CAMERA_HEIGHT, CAMERA_WIDTH
from epuck_ros.nodes.ack_window import COMMAND_QOS, HISTORY_BUDGET
from epuck_ros.nodes.robot_ports import JOINT_NAMES
from epuck_ros.nodes.sense_ports import SENSE_TOPICS
from epuck_ros.sensors.imu import gyro_values

LED_QOS = QoSProfile(depth=HISTORY_BUDGET, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Latched (a view started later still draws the LEDs), with the history of a controller's wheel_cmd (COMMAND_QOS):
a script may set them every step, and a reliable writer replaces a sample a recorder has not acknowledged yet once
its history is full. With a history of one, a 30 s recording lost 9 LED messages and a burst of 2,000 lost 302."""

QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
COMMAND_TOPIC = 'wheel_cmd'
SPIN_PERIOD = 0.1
"""Seconds one wait on the executor lasts at most, so that Ctrl-C and a vanished simulator are noticed."""
MISMATCH_GIVE_UP = 3
"""/clock messages since the answer after which an ir_raw count that does not match is accepted anyway."""
PARAMETER_RETRY = 5.0
"""Wall seconds after which the request for the simulator's time_step is sent again."""
ROBOT_CHOICE_GRACE = 3.0
"""Wall seconds the simulator's other robots may be in the graph without ours before `--robot` is refused."""


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
    'imu' ((ax, ay, az) m/s^2, gyro values (3)); a sense whose first message has not come yet is absent."""


class _SenseFeed:
    """The newest message of one sense topic, and whether it belongs to the step being gathered."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.value: Any = None
        self.stamp_ns: int | None = None
        self.since_answer = 0
        self.new = True
        """No message had come by the last answer: the counts of this step cannot be compared yet."""

    def on_message(self, msg: Any) -> None:
        if self.kind == 'camera':
            self.value = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)
        elif self.kind == 'imu':
            rates = (msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z)
            self.value = ((msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z),
                          tuple(gyro_values(np.array(rates), None).tolist()))
        else:
            self.value = tuple(msg.data)
        if self.kind in ('camera', 'imu'):
            self.stamp_ns = nanoseconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        self.since_answer += 1

    def ready(self, clock_ns: int, clocks: int) -> bool:
        """Its newest message is of the step stamped `clock_ns` (or it has sent none yet: not awaited)."""
        if self.value is None:
            return True
        if self.stamp_ns is not None:
            return self.stamp_ns == clock_ns
        if self.new:   # the first messages straddle the subscription (a step sent again, say): take the newest
            return self.since_answer > 0
        # At least one message per /clock since the answer (one more when a message of the step before came after
        # the answer: the newest is then this step's); fewer, and the step waits, as for ir_raw.
        return self.since_answer > 0 and (self.since_answer >= clocks or clocks >= MISMATCH_GIVE_UP)


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
        self._command = Float64MultiArray()
        self._publisher = self.node.create_publisher(Float64MultiArray, self._prefix + COMMAND_TOPIC, COMMAND_QOS)
        self._clock_ns: int | None = None
        self._joints: JointState | None = None
        self._ir_raw: tuple[float, ...] | None = None
        self._clocks_since_answer = 0
        self._ir_since_answer = 0
        self._consumed_ns = -1
        self._subscriptions = [
            self.node.create_subscription(Clock, '/clock', self._on_clock, QOS),
            self.node.create_subscription(JointState, self._prefix + 'joint_states', self._on_joints, QOS),
            self.node.create_subscription(Float64MultiArray, self._prefix + 'ir_raw', self._on_ir_raw, QOS)]
        self._feeds: dict[str, _SenseFeed] = {}
        self._subscriptions_of_senses: list = []
        self._led_publisher = None
        self.camera_size = (CAMERA_WIDTH, CAMERA_HEIGHT)
        """(width, height) of the simulator's camera images, known once `connect` has returned: a Camera built
        with it answers getWidth/getHeight right before its first image too (it takes the size of each image)."""

    # --- callbacks --------------------------------------------------------------------------------------------

    def _on_clock(self, msg: Clock) -> None:
        self._clock_ns = nanoseconds_from_stamp(msg.clock.sec, msg.clock.nanosec)
        self._clocks_since_answer += 1

    def _on_joints(self, msg: JointState) -> None:
        self._joints = msg

    def _on_ir_raw(self, msg: Float64MultiArray) -> None:
        self._ir_raw = tuple(msg.data)
        self._ir_since_answer += 1

    # --- connecting -------------------------------------------------------------------------------------------

    def connect(self) -> float | None:
        """Wait for the simulator and this robot's topics; the simulator's time step in seconds (None: stopped)."""
        if not self._wait(self._sim_in_graph, 'the simulator (a node publishing /clock)'):
            return None
        if not self._wait_for_robot():
            return None
        if not self._wait(self._matched, f'the simulator\'s {self._prefix}ir_raw and {self._prefix}joint_states'):
            return None
        return self._time_step()

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
        """From now on gather sense `kind` ('camera', 'ground', 'light', 'imu') with every step."""
        if kind in self._feeds:
            return
        feed = self._feeds[kind] = _SenseFeed(kind)
        message = {'camera': Image, 'imu': Imu}.get(kind, Float64MultiArray)
        self._subscriptions_of_senses.append(
            self.node.create_subscription(message, self._prefix + SENSE_TOPICS[kind], feed.on_message, QOS))

    def publish_leds(self, values: list[int]) -> None:
        """The ten LED values the script set (latched: a view started later still draws them)."""
        if self._led_publisher is None:
            self._led_publisher = self.node.create_publisher(Int32MultiArray, self._prefix + 'leds', LED_QOS)
        self._led_publisher.publish(Int32MultiArray(data=[int(v) for v in values]))

    def answer_and_wait(self, left: float, right: float) -> StepData | None:
        """Send the wheel speeds for the step last returned, then wait for the next one (None: stop or sim gone)."""
        self._clocks_since_answer = self._ir_since_answer = 0
        for feed in self._feeds.values():
            feed.since_answer, feed.new = 0, feed.value is None
        self._command.data = [float(left), float(right)]
        self._publisher.publish(self._command)
        return self._next_step()

    def _complete(self) -> bool:
        """The newest /clock, joint_states and ir_raw are one publication of the simulator, newer than the last.

        The simulator sends one of each per publication (ir_raw before /clock), in order on each topic. Joint states
        carry the stamp; ir_raw does not, so it is matched by count: as many since the answer as /clock messages.
        That also holds when the simulator went on without waiting (its lockstep_timeout): the readings then are
        those of its newest step, all three. Three publications without the counts meeting (a re-sent first step
        straddling the answer) and the newest ir_raw is taken as it is."""
        clock, clocks, joints = self._clock_ns, self._clocks_since_answer, self._joints
        return clock is not None and clock > self._consumed_ns and joints is not None and \
            nanoseconds_from_stamp(joints.header.stamp.sec, joints.header.stamp.nanosec) == clock and \
            self._ir_since_answer > 0 and \
            (self._ir_since_answer == clocks or clocks >= MISMATCH_GIVE_UP) and \
            all(feed.ready(clock, clocks) for feed in self._feeds.values())

    def _next_step(self) -> StepData | None:
        last_check = time.monotonic()
        while not self._complete():
            if self._stop_waiting():
                return None
            self._executor.spin_once(timeout_sec=SPIN_PERIOD)
            if time.monotonic() - last_check > SPIN_PERIOD:
                last_check = time.monotonic()
                if not self._sim_in_graph():
                    print('webots_controller: the simulator is gone', flush=True)
                    return None
        self._consumed_ns = self._clock_ns
        joints = self._joints
        index = {name.rsplit('/', 1)[-1]: i for i, name in enumerate(joints.name)}
        left, right = index[JOINT_NAMES[0]], index[JOINT_NAMES[1]]
        senses = {kind: feed.value for kind, feed in self._feeds.items() if feed.value is not None}
        return StepData(self._consumed_ns, (joints.position[left], joints.position[right]),
                        (joints.velocity[left], joints.velocity[right]), self._ir_raw, senses)

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()
