"""`bringup`: start the simulator, a behaviour and optionally the recorder, as separate processes.

ROS 2 launch is not available from PyPI, so this script does its job: every child gets
`use_sim_time`, the world, seed and real-time factor go to `sim`, and `-p name:=value` goes to the
node that declares `name` (or to the one named, as in `-p sim.noise:=false`). The run ends after
`--duration` simulated seconds, on Ctrl-C or SIGTERM, or when a child dies; in every case all
children are stopped (SIGINT, a bounded wait, then SIGKILL) and the exit code says whether all went well.
"""
from __future__ import annotations

import argparse
import collections
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import UInt32

from epuck_ros.nodes.sim_node import PARAMETERS as SIM_PARAMETERS

BEHAVIOURS = ('forward', 'spin', 'circle', 'rectangle', 'avoid')
STOP_ORDER = ('behaviour', 'record', 'sim')
"""The behaviour stops first so the robot is still simulated while the recorder closes its bag."""
READY_TIMEOUT = 30.0
RECORDER_TOPICS = ('odom', 'proximity', 'joint_states')
"""Simulator topics nothing but the recorder subscribes to yet when it starts: their subscribers are its own."""
SETTLE_TIME = 0.5
"""Wall seconds between seeing the behaviour's subscriptions in the graph and resuming the simulation, for the
simulator's publishers to match them too (the graph shows nothing of the matching itself). In lockstep the
simulator also re-sends its first step until the behaviour answers, so a late match costs no step there."""
STOP_TIMEOUT = 10.0
ERROR_LINES = 15


@dataclass
class Child:
    """A started executable: its process, and the tail of its output for error reports."""

    role: str
    name: str
    process: subprocess.Popen
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=ERROR_LINES))
    ready: threading.Event = field(default_factory=threading.Event)
    ready_text: str = ''

    def forward_output(self) -> None:
        """Echo the child's output with a prefix, keep its tail, and notice its ready line."""
        assert self.process.stdout is not None
        for line in self.process.stdout:
            line = line.rstrip('\n')
            self.tail.append(line)
            print(f'[{self.name}] {line}', flush=True)
            if self.ready_text and self.ready_text in line:
                self.ready.set()


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='bringup', description='Run the e-puck simulator with a course behaviour (and the MCAP recorder).',
        epilog='example: bringup rectangle --duration 30 -p turn_mode:=timed --record')
    parser.add_argument('behaviour', choices=BEHAVIOURS, help='the controller node to run')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='simulated seconds after which the run ends by itself (default: until Ctrl-C)')
    parser.add_argument('--world', default='', help='world YAML file (default: the built-in 1 m x 1 m arena)')
    parser.add_argument('--seed', type=int, default=0, help='seed of every random draw (default 0)')
    parser.add_argument('--real-time-factor', type=float, default=1.0,
                        help='simulated seconds per wall second; 0 = as fast as possible (default 1)')
    parser.add_argument('--no-noise', action='store_true', help='turn the sensor noise off')
    parser.add_argument('--lockstep', action='store_true',
                        help='the simulator waits for the behaviour\'s command after every step: the same run '
                             'whatever the load of the machine (pair it with --real-time-factor 0 for speed)')
    parser.add_argument('-p', '--param', action='append', default=[], metavar='[NODE.]NAME:=VALUE',
                        help='a parameter for the node that declares it (sim parameters go to sim, the rest to the '
                             'behaviour); repeatable')
    parser.add_argument('--record', nargs='?', const='', default=None, metavar='DIR',
                        help='record all topics to an MCAP bag (default folder: bags/<timestamp>)')
    parser.add_argument('--record-compression', choices=('none', 'zstd', 'lz4'), default='none',
                        help='chunk compression of the recording (default none, as rosbag2)')
    parser.add_argument('--namespace', default='', help='ROS namespace of the robot (e.g. robot1)')
    args = parser.parse_args(argv)
    if not math.isfinite(args.duration) or args.duration < 0:
        parser.error('--duration must be a non-negative number of simulated seconds')
    if not math.isfinite(args.real_time_factor) or args.real_time_factor < 0:
        parser.error('--real-time-factor must be >= 0')
    if args.world and not Path(args.world).is_file():
        parser.error(f'--world: no such file: {args.world}')
    args.sim_params, args.behaviour_params = route_parameters(parser, args)
    return args


def route_parameters(parser: argparse.ArgumentParser, args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """Split the `-p` assignments between sim and behaviour; the options above become sim parameters."""
    # The simulator starts paused; `run` resumes it once the behaviour is up, so both start at t = 0.
    sim = ['paused:=true', f'pause_at:={float(args.duration)}', f'seed:={args.seed}',
           f'world:={Path(args.world).resolve()}' if args.world else None,
           f'real_time_factor:={float(args.real_time_factor)}', 'noise:=false' if args.no_noise else None,
           'lockstep:=true' if args.lockstep else None]
    sim = [p for p in sim if p]
    behaviour = []
    for assignment in args.param:
        name, sep, value = assignment.partition(':=')
        if not sep or not name:
            parser.error(f'-p {assignment}: expected NAME:=VALUE')
        node, dot, short = name.rpartition('.')
        target = node if dot else ('sim' if name in SIM_PARAMETERS else 'behaviour')
        if target == args.behaviour:
            target = 'behaviour'
        if target not in ('sim', 'behaviour'):
            parser.error(f'-p {assignment}: unknown node {node!r} (use sim or {args.behaviour})')
        (sim if target == 'sim' else behaviour).append(f'{short if dot else name}:={value}')
    return sim, behaviour


def executable(name: str) -> str:
    """The package executable next to this one (venv bin/ or colcon lib/epuck_ros/), else on PATH."""
    sibling = Path(sys.argv[0]).resolve().parent / name
    found = str(sibling) if sibling.is_file() else shutil.which(name)
    if not found:
        raise SystemExit(f'bringup: cannot find the executable {name!r} next to {sys.argv[0]} or on PATH')
    return found


def start_child(role: str, name: str, params: list[str], namespace: str, args: tuple[str, ...] = (),
                ready_text: str = '') -> Child:
    """Start one executable with `use_sim_time`, its parameters and the namespace."""
    ros_args = ['--ros-args', '-p', 'use_sim_time:=true', *[arg for p in params for arg in ('-p', p)]]
    if namespace:
        ros_args += ['-r', f'__ns:=/{namespace.strip("/")}']
    # A session of its own: the terminal's Ctrl-C reaches bringup only, which then stops children in order.
    process = subprocess.Popen(
        [executable(name), *args, *ros_args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True, env=dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0'))
    child = Child(role, name, process, ready_text=ready_text)
    threading.Thread(target=child.forward_output, daemon=True).start()
    return child


def interrupt(process: subprocess.Popen, timeout: float) -> bool:
    """SIGINT, then SIGKILL after `timeout` seconds; False if it had to be killed."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            return False
    return True


def stop_children(children: list[Child]) -> list[str]:
    """Interrupt in STOP_ORDER, a bounded wait each; returns what went wrong."""
    problems = []
    for child in sorted(children, key=lambda c: STOP_ORDER.index(c.role)):
        if not interrupt(child.process, STOP_TIMEOUT):
            problems.append(f'{child.name} did not stop within {STOP_TIMEOUT:.0f} s of SIGINT and was killed')
            continue
        if child.process.returncode not in (0, -signal.SIGINT, 128 + signal.SIGINT):
            problems.append(f'{child.name} exited with code {child.process.returncode}')
    return problems


class RunMonitor:
    """Follows simulated time, distance travelled and collisions over DDS, for `--duration` and the summary."""

    def __init__(self, namespace: str) -> None:
        rclpy.init(args=['--ros-args', *(['-r', f'__ns:=/{namespace.strip("/")}'] if namespace else [])],
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node('bringup')
        self.sim_time = 0.0
        self.distance = 0.0
        self.collisions = 0
        self._last_xy: tuple[float, float] | None = None
        self.node.create_subscription(Clock, '/clock', self._on_clock, 10)
        self.node.create_subscription(Odometry, 'ground_truth', self._on_truth, 1000)  # every step counts
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(UInt32, 'collisions', self._on_collisions, latched)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _on_truth(self, msg: Odometry) -> None:
        xy = (msg.pose.pose.position.x, msg.pose.pose.position.y)
        if self._last_xy is not None:
            self.distance += math.dist(xy, self._last_xy)
        self._last_xy = xy

    def _on_collisions(self, msg: UInt32) -> None:
        self.collisions = msg.data

    def resume_sim(self, timeout: float) -> bool:
        """Set the simulator's `paused` parameter to false; True once it said yes."""
        client = AsyncParameterClient(self.node, 'sim')
        if not client.wait_for_services(timeout):
            return False
        future = client.set_parameters([Parameter('paused', value=False)])
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout)
        return future.done() and all(r.successful for r in future.result().results)

    def spin_once(self, timeout: float) -> None:
        rclpy.spin_once(self.node, timeout_sec=timeout)

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.try_shutdown()


class Supervisor:
    """Starts the children one after the other and watches them: a child that dies ends the run."""

    def __init__(self, args: argparse.Namespace, monitor: RunMonitor) -> None:
        self.args = args
        self.monitor = monitor
        self.children: list[Child] = []
        self.stop_requested = threading.Event()

    def watch(self, done: Callable[[], bool], timeout: float, what: str) -> str:
        """Spin until `done()` or a stop request (''), a child's death or the timeout (what went wrong)."""
        deadline = time.monotonic() + timeout
        while not self.stop_requested.is_set() and not done():
            self.monitor.spin_once(0.05)
            for child in self.children:
                if child.process.poll() is not None:
                    time.sleep(0.2)  # let its last lines arrive
                    lines = '\n  '.join(child.tail) or '(no output)'
                    return (f'{child.name} exited unexpectedly with code {child.process.returncode}; '
                            f'last lines:\n  {lines}')
            if time.monotonic() > deadline:
                return f'{what} within {timeout:.0f} s'
        return ''

    def start(self, role: str, name: str, params: list[str], args: tuple[str, ...] = (),
              ready_text: str = '') -> Child:
        child = start_child(role, name, params, self.args.namespace, args, ready_text)
        self.children.append(child)
        return child

    def behaviour_connected(self, name: str) -> bool:
        """The behaviour publishes wheel_cmd and every sim topic it subscribes to has a subscriber in the graph."""
        node = self.monitor.node
        if node.count_publishers('wheel_cmd') == 0:
            return False
        try:
            wanted = node.get_subscriber_names_and_types_by_node(name, node.get_namespace())
        except Exception:  # noqa: BLE001 - rclpy raises NodeNameNonExistentError until the node is discovered
            return False
        return all(node.count_subscribers(topic) > 0 for topic, _ in wanted)

    def run(self) -> str:
        """Start everything, resume the simulation, and watch until the end; returns what went wrong, if anything."""
        args = self.args
        sim = self.start('sim', 'sim', args.sim_params, ready_text='sim ready')
        failure = self.watch(sim.ready.is_set, READY_TIMEOUT, 'sim did not become ready')
        if not failure and args.record is not None:
            record_args = ('--compression', args.record_compression, *(('-o', args.record) if args.record else ()))
            recorder = self.start('record', 'record', [], record_args, ready_text='Recording')
            failure = self.watch(recorder.ready.is_set, READY_TIMEOUT, 'record did not start') or self.watch(
                lambda: all(self.monitor.node.count_subscribers(topic) > 0 for topic in RECORDER_TOPICS),
                READY_TIMEOUT, 'record did not subscribe to the simulator\'s topics')

        if not failure:
            self.start('behaviour', args.behaviour, args.behaviour_params)
            failure = self.watch(lambda: self.behaviour_connected(args.behaviour), READY_TIMEOUT,
                                 f'{args.behaviour} did not connect to the simulator')
        if failure or self.stop_requested.is_set():
            return failure
        time.sleep(SETTLE_TIME)
        if not self.monitor.resume_sim(READY_TIMEOUT):
            return 'sim did not accept paused:=false'
        print(f'[bringup] running {args.behaviour}' + (f' for {args.duration:g} simulated s' if args.duration else
                                                      ' until Ctrl-C'), flush=True)
        # The simulator pauses itself at exactly `pause_at` = duration: the run ends on that very step.
        return self.watch(lambda: bool(args.duration) and self.monitor.sim_time >= args.duration - 1e-6,
                          math.inf, '')


def run(args: argparse.Namespace) -> int:
    monitor = RunMonitor(args.namespace)
    supervisor = Supervisor(args, monitor)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: supervisor.stop_requested.set())
    wall_start = time.monotonic()
    failure = ''
    try:
        failure = supervisor.run()
    finally:
        # The figures are those of the run itself, not of the seconds the simulator keeps going while stopping.
        summary = RunSummary(monitor.sim_time, time.monotonic() - wall_start, monitor.distance, monitor.collisions)
        problems = stop_children(supervisor.children)
        monitor.close()
    if failure:
        problems.insert(0, failure)
    summary.print(problems)
    return 1 if problems else 0


@dataclass(frozen=True)
class RunSummary:
    """What the run did, as printed at its end."""

    sim_time: float
    wall_time: float
    distance: float
    collisions: int

    def print(self, problems: list[str]) -> None:
        speed = self.sim_time / self.wall_time if self.wall_time > 0 else 0.0
        print(f'[bringup] simulated {self.sim_time:.2f} s in {self.wall_time:.1f} s wall ({speed:.1f}x real time); '
              f'distance travelled {self.distance:.3f} m; collisions {self.collisions}', flush=True)
        for problem in problems:
            print(f'[bringup] error: {problem}', file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> None:
    sys.exit(run(parse_args(sys.argv[1:] if argv is None else argv)))


if __name__ == '__main__':
    main()
