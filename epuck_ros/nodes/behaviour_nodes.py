"""`forward`, `spin`, `circle`, `rectangle`, `avoid`: one node class around the pure behaviours.

Each executable is a row of `epuck_ros.behaviours.BEHAVIOURS`: the node declares that behaviour's settings
as read-only parameters, turns each step's `odom` and IR readings into an `Observation`, and answers the step
with the behaviour's wheel speeds on `wheel_cmd`, the course's `setVelocity` pair [left, right] in rad/s, naming
the step it answers (`BehaviourNode`). When it ends (Ctrl-C, SIGTERM) it commands a stop first.

One robot: the node's namespace is the robot's (`avoid --ros-args -r __ns:=/epuck3`). Several robots in one
process: `avoid --robots all` (every robot of the simulator's world) with use_sim_time is one node, a
`SwarmController`, that takes every robot's step in one `swarm/observation` message and answers in one
`swarm/command` (epuck_ros/swarm_messages.py), as fast as the simulator publishes. `avoid --robots epuck0 epuck1`
(names that may be real robots', or without use_sim_time) makes one node per robot, named like the executable, in
the namespace `<namespace>/<robot>`, all on one executor; `-p` parameters apply to every one of them. Beyond
FULL_NODES_UP_TO robots the nodes have only their behaviour's topics, and the process ends without destroying them
one by one (`SWARM_NODE_OPTIONS`).

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
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
import rclpy
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock as RosClock
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import InvalidNamespaceException, ParameterException
from rclpy.logging import LoggingSeverity
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rclpy.validate_namespace import validate_namespace
from sensor_msgs.msg import Range
from std_msgs.msg import Float64MultiArray, String

from epuck_ros.behaviours import BEHAVIOURS, BehaviourSpec, ConfigError, Observation, WheelCommand
from epuck_ros.behaviours.base import Behaviour, describe, ranges_from_raw, ranges_from_raw_rows
from epuck_ros.conversions import (nanoseconds_from_stamp, quaternion_from_yaw, stamp_from_nanoseconds,
                                   yaw_from_quaternion)
from epuck_ros.lockstep import Controller
from epuck_ros.model import SENSOR_NAMES, TIME_STEP
from epuck_ros.ros.ack_window import command_qos
from epuck_ros.ros.declaration import Declarer
from epuck_ros.ros.dds_profile import use_no_local_profile, use_package_profile, warn_if_not_fast_dds
from epuck_ros.ros.params import ParamSpec, Usage, declare_parameters, prepare_arguments, user_arguments
from epuck_ros.ros.qos import CONTROLLER_READS, LATCHED
from epuck_ros.ros.serialized import array_bytes, array_values
from epuck_ros.ros.spinning import end_process, handle_shutdown_signals, shutdown_requested, spin_until_shutdown
from epuck_ros.swarm_messages import (COMMAND_FIELDS, COMMAND_TOPIC, OBSERVATION_FIELDS, OBSERVATION_TOPIC,
                                      SwarmLayout, SwarmReader)
from epuck_ros.world import WorldError, world_from_yaml

CONTROL_PERIOD = TIME_STEP
"""Seconds between two decisions: the course's controllers run once per Webots basicTimeStep (32 ms)."""
STEP_SLACK_NS = 1_000
"""Nanoseconds a step may fall short of a whole control period and still be the next decision's (stamps are whole
nanoseconds of a float time)."""
QOS = CONTROLLER_READS
GRAPH_POLL_PERIOD = 0.1
"""Wall seconds between two looks at the graph for an `ir_raw` publisher (until there is one)."""
FALLBACK_DELAY = 1.0
"""Wall seconds `proximity` must have had a publisher without any `ir_raw` one before the node reads `proximity`:
the graph shows a simulator's publishers one by one, and the `ir_raw` one may come in a moment later."""
STOP_ACK_TIMEOUT = 1.0
"""Wall seconds an ending process waits for its robots' last (zero) wheel commands to be acknowledged."""
STOP_ACK_POLL = 0.005
"""Wall seconds between two looks at those acknowledgements."""
ALL_ROBOTS = 'all'
MAX_NAMES_SHOWN = 10
"""Robot names the start-up line lists at most (a swarm's thousands would make one line of tens of KB)."""
FULL_NODES_UP_TO = 50
"""Robots up to which a process's per-robot nodes are whole ROS nodes (parameter services, /rosout, the type
description service), destroyed one by one when it ends. Beyond, see SWARM_NODE_OPTIONS."""
SWARM_NODE_OPTIONS: dict[str, Any] = {
    'start_parameter_services': False, 'enable_rosout': False,
    'parameter_overrides': [Parameter('start_type_description_service', value=False)]}
"""A swarm's per-robot nodes: only the behaviour's topics (the parameters are read-only and the same on every node).
Each whole node has 16 more endpoints, which every other participant discovers, and matching each new one costs the
simulator time that grows with its own thousands: 200 whole nodes took 45 s to start and held the simulator's
start-up with them. Destroying a node costs Fast DDS time that grows with the process's other endpoints (checking
whether each type is still in use), so `avoid --robots all` with 200 robots took over 10 s to end after SIGTERM: a
swarm's process ends without it, once its last commands are acknowledged (test_swarm_bringup)."""


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


class Decisions:
    """A behaviour's answers to one robot's steps: a new decision every control period, on that step's data, and each
    step between answered with the last one (a per-robot node's and a swarm controller's rule). `log(line,
    standing)` is told each change of the behaviour's status; `standing`: the robot stands (waiting for an input,
    done)."""

    def __init__(self, behaviour: Behaviour, period_ns: int, log: Callable[[str, bool], None]) -> None:
        self.behaviour = behaviour
        self._period_ns = period_ns
        self._log = log
        self._decided: int | None = None
        """The step (ns) of the last decision, and the decision: answers until the next one (`control_period`)."""
        self._decision: WheelCommand | None = None
        self._logged_status = ''

    def answer(self, step: int, odom: tuple[float, float, float] | None,
               ranges: tuple[float, ...] | None) -> WheelCommand:
        """The answer to step `step` (ns), from that step's data."""
        if self._decision is None or step - self._decided >= self._period_ns - STEP_SLACK_NS:
            self._decision = self.decide(step, odom, ranges)
        return self._decision

    def decide(self, now: int, odom: tuple[float, float, float] | None,
               ranges: tuple[float, ...] | None) -> WheelCommand:
        """The behaviour's command at time `now` (ns) from these readings."""
        self._decided = now
        behaviour = self.behaviour
        command = behaviour.update(Observation(now * 1e-9, odom, ranges))
        if behaviour.status != self._logged_status:
            self._logged_status = behaviour.status
            self._log(f'{self._logged_status} (t={now * 1e-9:.3f} s)', bool(behaviour.waiting_for or behaviour.done))
        return command


def parameter_specs(spec: BehaviourSpec) -> list[ParamSpec]:
    """The behaviour's settings as read-only parameters (a behaviour is built once from them), and the period."""
    settings = [ParamSpec(name, value, description, None if low is None else (low, high), read_only=True)
                for name, value, description, (low, high) in describe(spec.defaults)]
    period = ParamSpec('control_period', CONTROL_PERIOD, 'seconds of the data\'s time between two decisions; every '
                       'step is answered (with the last decision between two); the course: one Webots step, 0.032',
                       (0.001, 1.0), read_only=True)
    return [*settings, period]


ROBOTS_HELP = '''  --robots NAME [NAME ...] | all
        drive several robots of the simulator from this one process: one node per robot, in the namespace
        <namespace>/<NAME> (the simulator's topics of that robot); all = every robot of the simulator's world
        (waits for the simulator). Without it, one node drives the robot of its namespace (-r __ns:=/epuck3).'''


def usage(name: str, spec: BehaviourSpec) -> Usage:
    return Usage(
        program=name,
        summary=f'{spec.summary}. Answers each simulator step with wheel_cmd [left, right] rad/s naming that step '
                f'(layout label stamp=SEC.NANOSEC: lockstep pairs it with the step), from odom and the IR readings '
                f'(ir_raw, or the eight proximity Range messages where nobody publishes ir_raw) of that step, or each '
                f'/clock tick (use_sim_time:=true) for a behaviour that reads nothing; commands a stop when it ends.',
        example=f'{name} --robots all --ros-args -p use_sim_time:=true {spec.example}'.rstrip(),
        options=ROBOTS_HELP)


class BehaviourNode(Node):
    """One robot's controller: subscribes what the behaviour needs, answers each step with `wheel_cmd`.

    The step protocol (epuck_ros/lockstep.py): every message of a simulator step names the step (odom's and the
    Ranges' stamps, `ir_raw`'s label), and the node answers step T once it has every input it needs from T, with a
    `wheel_cmd` that names T (`stamp=SEC.NANOSEC` in its layout). Nothing is paired by arrival order or counts, so a
    lockstep run repeats to the bit however late any message comes, and a step sent again is answered once. A
    behaviour that needs no input (spin, circle) answers each `/clock` tick. `control_period` longer than a step:
    the behaviour decides every period and each step between is answered with the last decision (lockstep waits for
    every step's answer). All this when the node follows simulated time (`use_sim_time`); on its own clock (a real
    robot's driver) it commands every `control_period` from the newest readings, naming no step.
    One `ir_raw` message carries all eight readings (the `proximity` path takes eight callbacks per step), so
    the node reads `proximity` only while the graph shows no `ir_raw` publisher (a real robot's driver), and never
    for a simulator's robots (`ir_raw_only`); an `ir_raw` that names no step is taken as the node's clock says.
    """

    def __init__(self, name: str, spec: BehaviourSpec, namespace: str | None = None, announce: bool = True,
                 ir_raw_only: bool = False, process_robots: int = 1, declarer: Declarer | None = None,
                 **options: Any) -> None:
        """`announce`: say the settings at INFO (else at DEBUG: the process's other nodes have said them).
        `ir_raw_only`: the robot is a simulator's (its `world` topic named it, `--robots all`), which always publishes
        `ir_raw`: the node never looks at the graph for `proximity`. Each look reads the whole graph; with each of 500
        nodes looking 10 times a second until its `ir_raw` publisher showed up, the process did nothing else, its
        DDS discovery starved and the simulator waited for its robots' answers (test_swarm_bringup).
        `process_robots`: how many robots this process drives (the history of `wheel_cmd`: `command_qos`).
        `declarer`: the process's (its first node makes it, `self.declarer`).
        `options`: rclpy Node's (SWARM_NODE_OPTIONS)."""
        super().__init__(name, cli_args=None if namespace is None else ['--ros-args', '-r', f'__ns:={namespace}'],
                         **options)
        if rclpy.logging.get_logger(name).is_enabled_for(LoggingSeverity.DEBUG):
            self.get_logger().set_level(LoggingSeverity.DEBUG)   # `--log-level avoid:=debug`: every robot's node
        settings = declare_parameters(self, parameter_specs(spec))
        period = settings.pop('control_period')
        self._decisions = Decisions(spec.make(replace(spec.defaults, **settings)), round(period * 1e9),
                                    self._log_status)
        self.behaviour = self._decisions.behaviour
        self._odom: tuple[float, float, float] | None = None
        self._ranges: tuple[float, ...] | None = None
        self._odom_stamp: int | None = None  # nanoseconds of the data above
        self._ranges_stamp: int | None = None
        self._answered: int | None = None
        """The step (ns) last answered."""
        self._last_answer: bytes | None = None
        """Its answer, as sent (a step sent again is answered with it again)."""
        self._assembler = RangeAssembler()
        self._range_subscription = None
        self._graph_timer = None
        self._proximity_polls = 0
        """Looks at the graph that showed a `proximity` publisher and no `ir_raw` one."""
        self._stepped = self.get_parameter('use_sim_time').value
        """Answers each simulator step (see the class); else commands every control_period of its own clock."""
        self._read_inputs(period, ir_raw_only)
        # Last: a lockstep simulator waits for the answers of a robot whose wheel_cmd has a publisher; declared
        # before it is made, lockstep knows from its first step how to wait for it (epuck_ros/lockstep.py).
        self.declarer = declarer or Declarer(self, process_robots)
        self.command_topics = [self.resolve_topic_name('wheel_cmd')]
        """The robot's command topic, fully qualified (what its declaration and its goodbye name)."""
        self.declarer.declare(Controller.LOCKSTEP if self._stepped else Controller.OWN_RATE, self.command_topics)
        self._publisher = self.create_publisher(Float64MultiArray, 'wheel_cmd', command_qos(process_robots))
        summary = ', '.join(f'{setting}={value}' for setting, value in settings.items())
        line = f'{spec.summary}; {summary}, control_period={period}'
        if announce:
            self.get_logger().info(line)
        else:
            self.get_logger().debug(line)

    def _read_inputs(self, period: float, ir_raw_only: bool) -> None:
        """Subscribe to what the behaviour reads; without simulated time, act on a timer of `period` instead."""
        if self.behaviour.needs_odom:
            self.create_subscription(Odometry, 'odom', self._on_odom, QOS)
        if self.behaviour.needs_proximity:
            self.create_subscription(Float64MultiArray, 'ir_raw', self._on_ir_raw, QOS, raw=True)
            if not ir_raw_only:
                self._graph_timer = self.create_timer(GRAPH_POLL_PERIOD, self._choose_ir_topic,
                                                      clock=Clock(clock_type=ClockType.STEADY_TIME))
        if not self._stepped:
            self.create_timer(period, self._on_tick)
        elif not (self.behaviour.needs_odom or self.behaviour.needs_proximity):
            self.create_subscription(RosClock, '/clock', self._on_clock, QOS)

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
        self._act_when_complete()

    def _on_ir_raw(self, data: bytes) -> None:
        read = array_values(data)  # received as bytes: see `serialized`
        if read is None or len(read[0]) != len(SENSOR_NAMES):
            got = 'bytes that are no Float64MultiArray' if read is None else f'messages of {len(read[0])} values'
            self.get_logger().warning(f'ir_raw: ignoring {got}, expected {len(SENSOR_NAMES)} values (ps0..ps7)',
                                      once=True)
            return
        raw, stamp = read
        self._ranges = ranges_from_raw(raw)
        self._ranges_stamp = self.get_clock().now().nanoseconds if stamp is None else nanoseconds_from_stamp(*stamp)
        self._act_when_complete()

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
            self._ranges_stamp = nanoseconds_from_stamp(*stamp)
            self._act_when_complete()

    def _on_clock(self, msg: RosClock) -> None:
        """A behaviour without inputs answers each tick of simulated time."""
        self._act(nanoseconds_from_stamp(msg.clock.sec, msg.clock.nanosec))

    def _on_tick(self) -> None:
        """On the node's own clock: a command every control_period from the newest readings, naming no step."""
        now = self.get_clock().now().nanoseconds
        self._publish(self._decisions.decide(now, self._odom, self._ranges), None)

    def _act_when_complete(self) -> None:
        """Answer the newest step once every input the behaviour needs is of that step (see the class)."""
        if not self._stepped:
            return
        stamps = [stamp for stamp, needed in ((self._odom_stamp, self.behaviour.needs_odom),
                                              (self._ranges_stamp, self.behaviour.needs_proximity)) if needed]
        if None not in stamps and len(set(stamps)) == 1:
            self._act(stamps[0])

    def _act(self, step: int) -> None:
        """Answer step `step` (ns): a new decision every control_period, the last one in between. A step the
        simulator sends again is answered again with the same bytes: it sends a step again while it has no answer
        (the answer may never have reached it: a writer that matched the simulator's reader only after publishing
        sends it nothing it had published), and drops a second identical answer as a repeat."""
        if self._answered is not None and step <= self._answered:
            if step == self._answered and self._last_answer is not None:
                self._publisher.publish(self._last_answer)
            return   # an older message come late: answered already
        self._answered = step
        command = self._decisions.answer(step, self._odom, self._ranges)
        self._last_answer = array_bytes((command.left, command.right), stamp_from_nanoseconds(step))
        self._publisher.publish(self._last_answer)

    def _log_status(self, line: str, standing: bool) -> None:
        if standing:   # the robot stands still: said at INFO
            self.get_logger().info(line)
        else:   # (two calls: rclpy refuses one call site logging at two severities)
            self.get_logger().debug(line)

    def _publish(self, command: WheelCommand, step: int | None) -> None:
        """`wheel_cmd`, naming `step` (ns) when it answers one."""
        self._publisher.publish(array_bytes((command.left, command.right),
                                            None if step is None else stamp_from_nanoseconds(step)))

    def stop_robot(self) -> None:
        """The last word, as teleop_twist_keyboard's: a zero wheel command, so that a robot without a command
        timeout does not drive on after its controller is gone (`wait_until_stopped` makes sure it arrived)."""
        self._publisher.publish(array_bytes((0.0, 0.0)))

    def stopped(self) -> bool:
        """Whether every reader acknowledged the zero command and the goodbye (not waiting: rclpy holds the GIL while
        it waits)."""
        return self._publisher.wait_for_all_acked(Duration(seconds=0)) and self.declarer.delivered()


_ODOM_X, _ODOM_Y, _ODOM_YAW = (OBSERVATION_FIELDS.index(field) for field in ('odom_x', 'odom_y', 'odom_yaw'))
_IR_RAW = slice(OBSERVATION_FIELDS.index('ps0_raw'), OBSERVATION_FIELDS.index('ps7_raw') + 1)


class SwarmController(Node):
    """Many robots of a simulator driven from one node: each step's `swarm/observation` in, one `swarm/command` out
    naming the step, with every robot's answer (epuck_ros/swarm_messages.py). Each robot has its own behaviour, asked as
    a `BehaviourNode` would ask it (the same `Decisions`, the odometry's yaw as it travels in a quaternion, the IR
    values through `ranges_from_raw_rows`: every robot's at once, the floats of `ranges_from_raw`), so the run is the
    one per-robot nodes drive, to the bit; one message each way per step instead of one per robot (and one `/clock`
    reader instead of one per robot).

    Before anything else it declares its robots on `swarm/command` (no fields: they are answered by name), so the
    simulator's lockstep waits for them from the moment it matches this node, however long the first answer takes."""

    def __init__(self, name: str, spec: BehaviourSpec, robots: Sequence[str]) -> None:
        super().__init__(name)
        settings = declare_parameters(self, parameter_specs(spec))
        period = settings.pop('control_period')
        config = replace(spec.defaults, **settings)
        self._robots = tuple(robots)
        self._decisions = [Decisions(spec.make(config), round(period * 1e9), partial(self._log_status, robot))
                           for robot in robots]
        self.behaviour = self._decisions[0].behaviour
        self._reader = SwarmReader()
        self._rows: tuple[tuple[str, ...], list[int] | None] = ((), None)
        """The observation's robots and the row of each of ours (None: one of ours is missing)."""
        self._answered: int | None = None
        """The step (ns) last answered."""
        self._last_answer: bytes | None = None
        """Its answer, as sent."""
        self._commands = SwarmLayout(self._robots, COMMAND_FIELDS)
        self._speeds = np.zeros((len(self._robots), len(COMMAND_FIELDS)))
        self.create_subscription(Float64MultiArray, OBSERVATION_TOPIC, self._on_observation, QOS, raw=True)
        self._publisher = self.create_publisher(Float64MultiArray, COMMAND_TOPIC, command_qos(len(self._robots)))
        self.declarer = Declarer(self, len(self._robots))
        """For its goodbye only: its robots are declared in lockstep by the swarm command's declaration."""
        self.command_topics = [self.resolve_topic_name(f'{robot}/wheel_cmd') for robot in self._robots]
        """Each robot's own command topic, fully qualified: what the simulator knows a robot's controller by."""
        self._publisher.publish(SwarmLayout(self._robots, ()).to_bytes(np.zeros((len(self._robots), 0)), None))
        summary = ', '.join(f'{setting}={value}' for setting, value in settings.items())
        self.get_logger().info(f'{spec.summary}; {summary}, control_period={period}; {len(robots)} robots through '
                               f'{self.resolve_topic_name(OBSERVATION_TOPIC)} and '
                               f'{self.resolve_topic_name(COMMAND_TOPIC)}')

    def _log_status(self, robot: str, line: str, standing: bool) -> None:
        if standing:   # the robot stands still: said at INFO
            self.get_logger().info(f'{robot}: {line}')
        else:   # (two calls: rclpy refuses one call site logging at two severities)
            self.get_logger().debug(f'{robot}: {line}')

    def _rows_of(self, robots: tuple[str, ...]) -> list[int] | None:
        if robots != self._rows[0]:
            index = {name: row for row, name in enumerate(robots)}
            missing = [name for name in self._robots if name not in index]
            if missing:
                self.get_logger().warning(f'{OBSERVATION_TOPIC} has no robot {missing[0]}: not answered', once=True)
            self._rows = (robots, None if missing else [index[name] for name in self._robots])
        return self._rows[1]

    def _on_observation(self, data: bytes) -> None:
        read = self._reader.read(data)
        if read is None or read.stamp is None or read.fields != OBSERVATION_FIELDS:
            self.get_logger().warning(f'{OBSERVATION_TOPIC}: ignoring a message that is no swarm observation of this '
                                      'version (a step named, fields as swarm_messages.OBSERVATION_FIELDS)', once=True)
            return
        step = nanoseconds_from_stamp(*read.stamp)
        rows = self._rows_of(read.robots)
        if rows is None:
            return
        if self._answered is not None and step <= self._answered:
            if step == self._answered and self._last_answer is not None:
                self._publisher.publish(self._last_answer)   # a step sent again (`BehaviourNode._act`)
            return   # an older message come late: answered already
        self._answered = step
        data = read.data[rows]
        behaviour = self.behaviour   # every robot's is of one kind: the same needs
        every_ranges = ranges_from_raw_rows(data[:, _IR_RAW]) if behaviour.needs_proximity else [None] * len(rows)
        answers = []
        for decisions, values, ranges in zip(self._decisions, data.tolist(), every_ranges):
            odom = (values[_ODOM_X], values[_ODOM_Y],
                    yaw_from_quaternion(0.0, 0.0, *quaternion_from_yaw(values[_ODOM_YAW]))) \
                if behaviour.needs_odom else None
            command = decisions.answer(step, odom, ranges)
            answers.append((command.left, command.right))
        speeds = self._speeds
        speeds[:] = answers
        self._last_answer = self._commands.to_bytes(speeds, read.stamp)
        self._publisher.publish(self._last_answer)

    def stop_robot(self) -> None:
        """A zero command for every robot, naming no step (`BehaviourNode.stop_robot`)."""
        self._publisher.publish(self._commands.to_bytes(np.zeros_like(self._speeds), None))

    def stopped(self) -> bool:
        """Whether every reader acknowledged the zero commands and the goodbye (`BehaviourNode.stopped`)."""
        return self._publisher.wait_for_all_acked(Duration(seconds=0)) and self.declarer.delivered()


def wait_until_stopped(nodes: Sequence[BehaviourNode], timeout: float) -> None:
    """Wait until every reader acknowledged each node's zero command, `timeout` for them all: a busy reader may have
    dropped it on arrival, and only its writer, still alive, can send it again (without this wait it was lost in about
    half the exits). One warning for those still unacknowledged (a swarm's each got its own line)."""
    deadline = time.monotonic() + timeout
    waiting = list(nodes)
    while waiting:
        waiting = [node for node in waiting if not node.stopped()]
        if waiting and time.monotonic() >= deadline:
            names = ', '.join(node.get_namespace() for node in waiting[:3]) + (', ...' if len(waiting) > 3 else '')
            waiting[0].get_logger().warning(f'the last (zero) wheel command of {len(waiting)} robot(s) ({names}) was '
                                            f'not acknowledged within {timeout:.1f} s')
            return
        if waiting:
            time.sleep(STOP_ACK_POLL)


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


def _follows_sim_time(name: str) -> bool:
    """Whether the command line sets use_sim_time (the nodes answer the simulator's steps: `--robots all` on several
    robots is then one `SwarmController`); else each robot's node commands on its own clock."""
    probe = Node(f'{name}_clock', enable_rosout=False, start_parameter_services=False)
    try:
        return bool(probe.get_parameter('use_sim_time').value)
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
    use_no_local_profile()  # its nodes never read each other's topics
    use_package_profile()  # its quick heartbeats: the last (zero) wheel command is acknowledged within STOP_ACK_TIMEOUT
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    warn_if_not_fast_dds(rclpy.logging.get_logger(name))
    handle_shutdown_signals()
    nodes: list[BehaviourNode] = []
    swarm = False
    code: int | None = None
    """The exit code, once known (None: an unexpected error, whose traceback follows)."""
    try:
        namespaces = robot_namespaces(name, robots)
        if robots == [ALL_ROBOTS] and len(namespaces) > 1 and _follows_sim_time(name):
            nodes.append(SwarmController(name, spec, [namespace.rsplit('/', 1)[-1] for namespace in namespaces]))
            namespaces = []
        swarm = len(namespaces) > FULL_NODES_UP_TO
        for namespace in namespaces:
            if shutdown_requested():  # SIGTERM while a swarm's nodes are made: no need to make the others
                break
            nodes.append(BehaviourNode(name, spec, namespace, announce=not nodes, ir_raw_only=robots == [ALL_ROBOTS],
                                       process_robots=len(namespaces), declarer=nodes[0].declarer if nodes else None,
                                       **(SWARM_NODE_OPTIONS if swarm else {})))
        if nodes and not shutdown_requested():
            spin_until_shutdown(*nodes, executor_type=EventsExecutor)
        code = 0
    except (ConfigError, ParameterException, InvalidNamespaceException, WorldError) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        code = 2
    finally:
        stopping = [node for node in nodes if node.context.ok()]
        if stopping:   # a lockstep simulator that still runs goes on without them (epuck_ros/lockstep.py)
            stopping[0].declarer.goodbye([topic for node in stopping for topic in node.command_topics])
        for node in stopping:
            node.stop_robot()
        wait_until_stopped(stopping, STOP_ACK_TIMEOUT)
        if swarm and code is not None:
            end_process(code)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    if code:
        raise SystemExit(code)


main_forward = partial(main, 'forward')
main_spin = partial(main, 'spin')
main_circle = partial(main, 'circle')
main_rectangle = partial(main, 'rectangle')
main_avoid = partial(main, 'avoid')
