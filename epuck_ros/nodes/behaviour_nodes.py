"""`forward`, `spin`, `circle`, `rectangle`, `avoid`: one node class around the pure behaviours.

Each executable is a row of `epuck_ros.behaviours.BEHAVIOURS`: the node declares that behaviour's settings
as read-only parameters, turns `odom` and the IR readings into an `Observation`, and on a ROS-clock timer
(so it follows `use_sim_time`) publishes the behaviour's wheel speeds on `wheel_cmd` as the course's
`setVelocity` pair [left, right] in rad/s. When it ends (Ctrl-C, SIGTERM) it commands a stop first.

One robot: the node's namespace is the robot's (`avoid --ros-args -r __ns:=/epuck3`). Several robots in one
process: `avoid --robots epuck0 epuck1` (or `--robots all`, every robot of the simulator's world) makes one
node per robot, named like the executable, in the namespace `<namespace>/<robot>`, all on one executor;
`-p` parameters apply to every one of them.

Logging: each node says its settings at start (the first node only, when one process drives several robots: they
share them), and at INFO what leaves the robot standing (waiting for an input, the goal reached); the behaviour's
other state changes (cruising, turning, a new side) at DEBUG, since some change every few steps:
`--ros-args --log-level avoid:=debug` (the executable's name; `bringup --verbose`) shows them for every robot's node.

The nodes spin on rclpy's EventsExecutor (experimental in Jazzy, in rclpy since 7.1.4): it queues each ready
entity's event in C++ instead of rebuilding a wait set of every node's subscriptions, timers and parameter
services in Python before each callback: less CPU per lockstep step than SingleThreadedExecutor
(benchmarks/bench_lockstep.py; its figures are in the README).
"""
from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from dataclasses import replace
from functools import partial
from typing import Any

import rclpy
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import InvalidNamespaceException, ParameterException
from rclpy.logging import LoggingSeverity
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.validate_namespace import validate_namespace
from sensor_msgs.msg import Range
from std_msgs.msg import Float64MultiArray, String

from epuck_ros.behaviours import BEHAVIOURS, BehaviourSpec, ConfigError, Observation
from epuck_ros.behaviours.base import describe, ranges_from_raw
from epuck_ros.conversions import nanoseconds_from_stamp, yaw_from_quaternion
from epuck_ros.model import SENSOR_NAMES, TIME_STEP
from epuck_ros.nodes.ack_window import COMMAND_QOS
from epuck_ros.nodes.dds_profile import use_package_profile, warn_if_not_fast_dds
from epuck_ros.nodes.params import ParamSpec, Usage, declare_parameters, prepare_arguments, user_arguments
from epuck_ros.nodes.qos import LATCHED
from epuck_ros.nodes.serialized import Patch, float64_values
from epuck_ros.nodes.spinning import handle_shutdown_signals, shutdown_requested, spin_until_shutdown
from epuck_ros.world import WorldError, world_from_yaml

CONTROL_PERIOD = TIME_STEP
"""Seconds between two commands: the course's controllers run once per Webots basicTimeStep (32 ms)."""
QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
GRAPH_POLL_PERIOD = 0.1
"""Wall seconds between two looks at the graph for an `ir_raw` publisher (until there is one)."""
FALLBACK_DELAY = 1.0
"""Wall seconds `proximity` must have had a publisher without any `ir_raw` one before the node reads `proximity`:
the graph shows a simulator's publishers one by one, and the `ir_raw` one may come in a moment later."""
STOP_ACK_TIMEOUT = 1.0
"""Wall seconds an ending process waits for its robots' last (zero) wheel commands to be acknowledged."""
ALL_ROBOTS = 'all'
MAX_NAMES_SHOWN = 10
"""Robot names the start-up line lists at most (a swarm's thousands would make one line of tens of KB)."""


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


def parameter_specs(spec: BehaviourSpec) -> list[ParamSpec]:
    """The behaviour's settings as read-only parameters (a behaviour is built once from them), and the period."""
    settings = [ParamSpec(name, value, description, None if low is None else (low, high), read_only=True)
                for name, value, description, (low, high) in describe(spec.defaults)]
    period = ParamSpec('control_period', CONTROL_PERIOD, 'seconds (ROS clock) between two wheel commands; the course: '
                       'one Webots step, 0.032 (avoid on ir_raw answers every ir_raw message)', (0.001, 1.0),
                       read_only=True)
    return [*settings, period]


ROBOTS_HELP = '''  --robots NAME [NAME ...] | all
        drive several robots of the simulator from this one process: one node per robot, in the namespace
        <namespace>/<NAME> (the simulator's topics of that robot); all = every robot of the simulator's world
        (waits for the simulator). Without it, one node drives the robot of its namespace (-r __ns:=/epuck3).'''


def usage(name: str, spec: BehaviourSpec) -> Usage:
    return Usage(
        program=name,
        summary=f'{spec.summary}. Publishes wheel_cmd [left, right] rad/s every control_period (ROS clock: '
                f'use_sim_time:=true follows the simulator), from odom and the IR readings (ir_raw, or the eight '
                f'proximity Range messages where nobody publishes ir_raw); commands a stop when it ends.',
        example=f'{name} --robots all --ros-args -p use_sim_time:=true {spec.example}'.rstrip(),
        options=ROBOTS_HELP)


class BehaviourNode(Node):
    """One robot's controller: subscribes what the behaviour needs, publishes `wheel_cmd` every control period.

    Each command answers exactly one step. `/clock` (the tick) and the sensor topics travel separately, so a
    tick can arrive before or after its data; the node acts on a tick once every input it needs is there for
    it (`_act_when_ready`), which makes lockstep runs repeat to the bit:
    - stamped inputs (`odom`, the `proximity` Ranges) are there once their stamp reaches the tick;
    - `ir_raw` has no header: it counts as there when one arrived since the last command. In lockstep that is
      exactly this step's: the simulator publishes the next step only once this command answered the current
      one, so the only unanswered `ir_raw` is the current step's, whichever of it and the tick comes first.
    A behaviour that needs the IR alone (avoid) does not wait for the tick at all once `ir_raw` flows: it answers
    each message as it arrives, one command per simulator step (whatever `control_period`). `/clock` reaches the
    node after the step's `ir_raw` (the simulator sends it last), and waiting for it costs more than the step
    itself (bench_lockstep in the README).
    The command's time is then the previous command's plus one period, or the clock if that is later (a step
    answered late, outside lockstep): in lockstep exactly the step's time, whichever of `ir_raw` and `/clock`
    came first.
    One `ir_raw` message carries all eight readings (the `proximity` path takes eight callbacks per step), so
    the node reads `proximity` only while the graph shows no `ir_raw` publisher (a real robot's driver).
    """

    def __init__(self, name: str, spec: BehaviourSpec, namespace: str | None = None, announce: bool = True) -> None:
        """`announce`: say the settings at INFO (else at DEBUG: the process's other nodes have said them)."""
        super().__init__(name, cli_args=None if namespace is None else ['--ros-args', '-r', f'__ns:={namespace}'])
        if rclpy.logging.get_logger(name).is_enabled_for(LoggingSeverity.DEBUG):
            self.get_logger().set_level(LoggingSeverity.DEBUG)   # `--log-level avoid:=debug`: every robot's node
        settings = declare_parameters(self, parameter_specs(spec))
        period = settings.pop('control_period')
        self.behaviour = spec.make(replace(spec.defaults, **settings))
        self._odom: tuple[float, float, float] | None = None
        self._ranges: tuple[float, ...] | None = None
        self._odom_stamp: int | None = None  # nanoseconds of the data above
        self._ranges_stamp: int | None = None
        self._fresh_raw = False
        """An ir_raw message arrived since the last command."""
        self._pending_tick: int | None = None
        self._last_tick: int | None = None
        self._raw_drives = False
        """`ir_raw` messages come and the behaviour needs nothing else: each one is answered as it arrives."""
        self._late_ticks = 0
        self._assembler = RangeAssembler()
        self._range_subscription = None
        self._graph_timer = None
        self._proximity_polls = 0
        """Looks at the graph that showed a `proximity` publisher and no `ir_raw` one."""
        if self.behaviour.needs_odom:
            self.create_subscription(Odometry, 'odom', self._on_odom, QOS)
        if self.behaviour.needs_proximity:
            self.create_subscription(Float64MultiArray, 'ir_raw', self._on_ir_raw, QOS, raw=True)
            self._graph_timer = self.create_timer(GRAPH_POLL_PERIOD, self._choose_ir_topic,
                                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
        # Last: a lockstep simulator waits for the answers of a robot whose wheel_cmd has a publisher.
        self._publisher = self.create_publisher(Float64MultiArray, 'wheel_cmd', COMMAND_QOS)
        self._command = Patch(Float64MultiArray(data=[0.0, 0.0]), [('data[0]', 'd'), ('data[1]', 'd')])
        """wheel_cmd as CDR bytes (see `serialized`): a step's command costs no message conversion."""
        self._logged_status = ''
        self._period_ns = round(period * 1e9)
        self._tick_timer = self.create_timer(period, self._on_tick)
        summary = ', '.join(f'{setting}={value}' for setting, value in settings.items())
        line = f'{spec.summary}; {summary}, control_period={period}'
        if announce:
            self.get_logger().info(line)
        else:
            self.get_logger().debug(line)

    def _choose_ir_topic(self) -> None:
        """`ir_raw` once it has a publisher; until then `proximity` once that has had one for FALLBACK_DELAY (a
        real robot's driver)."""
        if self.count_publishers(self.resolve_topic_name('ir_raw')) > 0:
            self.destroy_timer(self._graph_timer)
            if self._range_subscription is not None:
                self.destroy_subscription(self._range_subscription)
                self._range_subscription = None
                self.get_logger().info('ir_raw has a publisher now: reading it instead of proximity')
        elif self._range_subscription is None and self.count_publishers(self.resolve_topic_name('proximity')) > 0:
            self._proximity_polls += 1
            if self._proximity_polls * GRAPH_POLL_PERIOD >= FALLBACK_DELAY:
                self._range_subscription = self.create_subscription(Range, 'proximity', self._on_range, QOS)
                self.get_logger().info('nobody publishes ir_raw: reading the eight proximity Range messages of '
                                       'each step')

    def _on_odom(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        q = pose.orientation
        self._odom = (pose.position.x, pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))
        self._odom_stamp = nanoseconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        self._act_when_ready()

    def _on_ir_raw(self, data: bytes) -> None:
        """A behaviour on the IR alone answers each `ir_raw` message at once (see the class)."""
        raw = float64_values(data)  # received as bytes: see `serialized`
        if raw is None or len(raw) != len(SENSOR_NAMES):
            got = 'bytes that are no Float64MultiArray' if raw is None else f'messages of {len(raw)} values'
            self.get_logger().warning(f'ir_raw: ignoring {got}, expected {len(SENSOR_NAMES)} values (ps0..ps7)',
                                      once=True)
            return
        self._ranges = ranges_from_raw(raw)
        if self.behaviour.needs_odom:
            self._fresh_raw = True
            self._act_when_ready()
            return
        if not self._raw_drives:  # from now on the messages drive the node; its ticks cost time for nothing
            self._raw_drives = True
            self.destroy_timer(self._tick_timer)
        tick = self._pending_tick if self._pending_tick is not None else self.get_clock().now().nanoseconds
        if self._last_tick is not None:
            tick = max(tick, self._last_tick + self._period_ns)
        self._act(tick)

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
            self._ranges_stamp = nanoseconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
            self._act_when_ready()

    def _on_tick(self) -> None:
        if self._pending_tick is not None:  # its data never came complete: act on what there is
            if self._odom is not None or self._ranges is not None:
                self._late_ticks += 1
                self.get_logger().warning(
                    f'acting on t={self._pending_tick * 1e-9:.3f} s without that step\'s data: it came late (a '
                    'busy machine, or a simulator faster than this node: use lockstep); said once, counted',
                    once=True)
            self._act(self._pending_tick)
        self._pending_tick = self.get_clock().now().nanoseconds
        self._act_when_ready()

    def _has_data_for(self, tick: int) -> bool:
        if self.behaviour.needs_odom and (self._odom_stamp is None or self._odom_stamp < tick):
            return False
        if self.behaviour.needs_proximity and self._range_subscription is None:
            return self._fresh_raw
        if self.behaviour.needs_proximity:
            return self._ranges_stamp is not None and self._ranges_stamp >= tick
        return True

    def _act_when_ready(self) -> None:
        """Act on the pending tick once every input the behaviour needs is there for it (see the class)."""
        if self._pending_tick is not None and self._has_data_for(self._pending_tick):
            self._act(self._pending_tick)

    def _act(self, tick: int) -> None:
        self._pending_tick = None
        self._last_tick = tick
        self._fresh_raw = False
        now = tick * 1e-9
        command = self.behaviour.update(Observation(now, self._odom, self._ranges))
        if self.behaviour.status != self._logged_status:
            self._logged_status = self.behaviour.status
            line = f'{self._logged_status} (t={now:.3f} s)'
            if self.behaviour.waiting_for or self.behaviour.done:   # the robot stands still: said at INFO
                self.get_logger().info(line)
            else:   # (two calls: rclpy refuses one call site logging at two severities)
                self.get_logger().debug(line)
        self._publisher.publish(self._command.bytes((command.left, command.right)))

    def stop_robot(self) -> None:
        """The last word, as teleop_twist_keyboard's: a zero wheel command, so that a robot without a command
        timeout does not drive on after its controller is gone (`wait_until_stopped` makes sure it arrived)."""
        if self._late_ticks:
            self.get_logger().warning(f'{self._late_ticks} tick(s) acted on without their step\'s data')
        self._publisher.publish(self._command.bytes((0.0, 0.0)))

    def wait_until_stopped(self, timeout: float) -> None:
        """Wait until every reader acknowledged the zero command: a busy reader may have dropped it on arrival, and
        only this writer, still alive, can send it again (without this wait it was lost in about half the exits)."""
        if not self._publisher.wait_for_all_acked(Duration(seconds=max(timeout, 0.0))):
            self.get_logger().warning(f'the last (zero) wheel command was not acknowledged within {timeout:.1f} s')


def parse_robots(name: str, user_args: list[str]) -> list[str] | None:
    """The `--robots` names (or ['all']), None without the option; exits 2 on anything else."""
    parser = argparse.ArgumentParser(prog=name, add_help=False,
                                     usage=f'{name} [--robots NAME [NAME ...] | all] [--ros-args ...]')
    parser.add_argument('--robots', nargs='+', metavar='NAME')
    robots = parser.parse_args(user_args).robots
    if robots and ALL_ROBOTS in robots and len(robots) > 1:
        parser.error(f'--robots: {ALL_ROBOTS} stands alone')
    if robots and len(set(robots)) != len(robots):
        parser.error(f'--robots: a name is given twice: {" ".join(robots)}')
    return robots


def robot_namespaces(name: str, robots: list[str] | None) -> list[str | None]:
    """One namespace per node to make: [None] = one node where the command line puts it; [] = shut down meanwhile.

    The robots' namespaces are relative to the one the command line gives (`-r __ns:=/lab`), as the simulator's
    robot topics are relative to its own. `all` reads the robot names from the simulator's latched `world`
    topic; a world of one robot has its topics in the simulator's namespace itself."""
    if robots is None:
        return [None]
    probe = Node(f'{name}_robots', enable_rosout=False, start_parameter_services=False)
    try:
        base = probe.get_namespace().rstrip('/')
        if robots == [ALL_ROBOTS]:
            robots = _world_robots(probe)
            if robots is None:
                return []
            if len(robots) == 1:
                return [base or '/']
        namespaces = [f'{base}/{robot}' for robot in robots]
        for namespace in namespaces:
            validate_namespace(namespace)
        return namespaces
    finally:
        probe.destroy_node()


def _world_robots(probe: Node) -> list[str] | None:
    """The robot names of the simulator's world, waiting for the simulator; None if asked to shut down first."""
    received: list[String] = []
    probe.create_subscription(String, 'world', received.append, LATCHED)
    probe.get_logger().info(f'waiting for the simulator ({probe.resolve_topic_name("world")}) to learn its robots')
    spin_until_shutdown(probe, until=lambda: bool(received))
    if not received:
        return None
    world = world_from_yaml(received[-1].data, source=probe.resolve_topic_name('world'))
    names = [robot.name for robot in world.robots]
    shown = names if len(names) <= MAX_NAMES_SHOWN else [*names[:MAX_NAMES_SHOWN - 1], '...', names[-1]]
    probe.get_logger().info(f'driving {len(names)} robot(s): {" ".join(shown)}')
    return names


def main(name: str, args: list[str] | None = None) -> None:
    spec = BEHAVIOURS[name]
    argv = prepare_arguments(args, parameter_specs(spec), usage(name, spec), own_options=True)
    robots = parse_robots(name, user_arguments(argv))
    use_package_profile()  # its quick heartbeats: the last (zero) wheel command is acknowledged within STOP_ACK_TIMEOUT
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    warn_if_not_fast_dds(rclpy.logging.get_logger(name))
    handle_shutdown_signals()
    nodes: list[BehaviourNode] = []
    try:
        for namespace in robot_namespaces(name, robots):
            nodes.append(BehaviourNode(name, spec, namespace, announce=not nodes))
        if nodes and not shutdown_requested():
            spin_until_shutdown(*nodes, executor_type=EventsExecutor)
    except (ConfigError, ParameterException, InvalidNamespaceException, WorldError) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        raise SystemExit(2)
    finally:
        stopping = [node for node in nodes if node.context.ok()]
        for node in stopping:
            node.stop_robot()
        deadline = time.monotonic() + STOP_ACK_TIMEOUT
        for node in stopping:
            node.wait_until_stopped(deadline - time.monotonic())
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()


main_forward = partial(main, 'forward')
main_spin = partial(main, 'spin')
main_circle = partial(main, 'circle')
main_rectangle = partial(main, 'rectangle')
main_avoid = partial(main, 'avoid')
