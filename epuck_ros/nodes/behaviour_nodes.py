"""`forward`, `spin`, `circle`, `rectangle`, `avoid`: one node class around the pure behaviours.

Each executable is a row of `epuck_ros.behaviours.BEHAVIOURS`: the node declares that behaviour's settings
as read-only parameters, turns `odom` and the eight `proximity` Range messages of a sensing cycle into an
`Observation`, and on a ROS-clock timer (so it follows `use_sim_time`) publishes the behaviour's wheel
speeds on `wheel_cmd` as the course's `setVelocity` pair [left, right] in rad/s.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from functools import partial
from typing import Any

import rclpy
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Range
from std_msgs.msg import Float64MultiArray

from epuck_ros.behaviours import BEHAVIOURS, BehaviourSpec, ConfigError, Observation
from epuck_ros.behaviours.base import describe
from epuck_ros.model import SENSOR_NAMES
from epuck_ros.nodes.spinning import spin_until_shutdown

CONTROL_PERIOD = 0.032
"""Seconds between two commands: the course's controllers run once per Webots basicTimeStep (32 ms)."""
QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class RangeAssembler:
    """Collects the Range messages of one sensing cycle (one shared stamp, one per sensor frame) into a tuple
    in sensor order. A cycle that a newer stamp interrupts is dropped, so readings are never mixed."""

    def __init__(self, names: Sequence[str] = SENSOR_NAMES) -> None:
        self._index = {name: i for i, name in enumerate(names)}
        self._values = [math.nan] * len(names)
        self._stamp: Any = None
        self._missing: set[int] = set()

    def add(self, frame_id: str, stamp: Any, value: float) -> tuple[float, ...] | None:
        """The complete cycle when this message completes it, else None; KeyError for an unknown sensor.

        A frame prefix (`robot1/ps0`, the sim's `frame_prefix`) is ignored."""
        index = self._index[frame_id.rsplit('/', 1)[-1]]
        if stamp != self._stamp:
            self._stamp, self._missing = stamp, set(self._index.values())
        if index not in self._missing:
            return None
        self._missing.remove(index)
        self._values[index] = value
        return None if self._missing else tuple(self._values)


def _nanoseconds(stamp: Any) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _descriptor(description: str, value: Any, low: Any, high: Any) -> ParameterDescriptor:
    """Read-only: a behaviour is built once from its settings."""
    descriptor = ParameterDescriptor(description=description, read_only=True)
    if low is None:
        return descriptor
    if isinstance(value, int):
        descriptor.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    else:
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    return descriptor


class BehaviourNode(Node):
    """Subscribes what the behaviour needs (`odom`, `proximity`), publishes `wheel_cmd` every control period."""

    def __init__(self, name: str, spec: BehaviourSpec) -> None:
        super().__init__(name)
        settings = {
            setting: self.declare_parameter(setting, value, _descriptor(description, value, low, high)).value
            for setting, value, description, (low, high) in describe(spec.defaults)}
        period = self.declare_parameter('control_period', CONTROL_PERIOD, _descriptor(
            'seconds (ROS clock) between two wheel commands; the course: one Webots step, 0.032',
            CONTROL_PERIOD, 0.001, 1.0)).value
        self.behaviour = spec.make(replace(spec.defaults, **settings))
        self._odom: tuple[float, float, float] | None = None
        self._ranges: tuple[float, ...] | None = None
        self._odom_stamp: int | None = None  # nanoseconds of the data above
        self._ranges_stamp: int | None = None
        self._pending_tick: int | None = None
        self._assembler = RangeAssembler()
        if self.behaviour.needs_odom:
            self.create_subscription(Odometry, 'odom', self._on_odom, QOS)
        if self.behaviour.needs_proximity:
            self.create_subscription(Range, 'proximity', self._on_range, QOS)
        self._publisher = self.create_publisher(Float64MultiArray, 'wheel_cmd', QOS)
        self._command = Float64MultiArray()
        self._logged_status = ''
        self.create_timer(period, self._on_tick)
        summary = ', '.join(f'{setting}={value}' for setting, value in settings.items())
        self.get_logger().info(f'{spec.summary}; {summary}, control_period={period}')

    def _on_odom(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        q = pose.orientation
        self._odom = (pose.position.x, pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))
        self._odom_stamp = _nanoseconds(msg.header.stamp)
        self._act_when_ready()

    def _on_range(self, msg: Range) -> None:
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        try:
            ranges = self._assembler.add(msg.header.frame_id, stamp, msg.range)
        except KeyError:
            self.get_logger().warning(
                f'proximity: ignoring frame_id {msg.header.frame_id!r}, expected one of {", ".join(SENSOR_NAMES)}',
                once=True)
            return
        if ranges is not None:
            self._ranges = ranges
            self._ranges_stamp = _nanoseconds(msg.header.stamp)
            self._act_when_ready()

    def _on_tick(self) -> None:
        if self._pending_tick is not None:  # its data never came complete: act on what there is
            self._act(self._pending_tick)
        self._pending_tick = self.get_clock().now().nanoseconds
        self._act_when_ready()

    def _act_when_ready(self) -> None:
        """Act on the pending tick once every input the behaviour needs carries that tick's stamp or a later one.

        `/clock` and the sensor topics travel separately, so a tick can arrive before its own data; waiting for it
        makes every command answer the same observation whatever the timing (and lockstep runs repeatable)."""
        if self._pending_tick is None:
            return
        stamps = [self._odom_stamp] if self.behaviour.needs_odom else []
        stamps += [self._ranges_stamp] if self.behaviour.needs_proximity else []
        if all(stamp is not None and stamp >= self._pending_tick for stamp in stamps):
            self._act(self._pending_tick)

    def _act(self, tick: int) -> None:
        self._pending_tick = None
        now = tick * 1e-9
        command = self.behaviour.update(Observation(now, self._odom, self._ranges))
        if self.behaviour.status != self._logged_status:
            self._logged_status = self.behaviour.status
            self.get_logger().info(f'{self._logged_status} (t={now:.3f} s)')
        self._command.data = [command.left, command.right]
        self._publisher.publish(self._command)


def main(name: str, args: list[str] | None = None) -> None:
    rclpy.init(args=args)
    node = None
    try:
        node = BehaviourNode(name, BEHAVIOURS[name])
        spin_until_shutdown(node)
    except (ConfigError, ParameterException) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        raise SystemExit(2)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


main_forward = partial(main, 'forward')
main_spin = partial(main, 'spin')
main_circle = partial(main, 'circle')
main_rectangle = partial(main, 'rectangle')
main_avoid = partial(main, 'avoid')
