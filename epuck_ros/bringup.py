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
from dataclasses import dataclass, field
from pathlib import Path

BEHAVIOURS = ('forward', 'spin', 'circle', 'rectangle', 'avoid')
SIM_PARAMETERS = ('time_step', 'real_time_factor', 'world', 'seed', 'noise', 'cmd_timeout', 'cmd_vel_stamped',
                  'frame_prefix')
STOP_ORDER = ('behaviour', 'record', 'sim')
"""The behaviour stops first so the robot is still simulated while the recorder closes its bag."""
READY_TIMEOUT = 30.0
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
    parser.add_argument('-p', '--param', action='append', default=[], metavar='[NODE.]NAME:=VALUE',
                        help='a parameter for the node that declares it (sim parameters go to sim, the rest to the '
                             'behaviour); repeatable')
    parser.add_argument('--record', nargs='?', const='', default=None, metavar='DIR',
                        help='record all topics to an MCAP bag (default folder: bags/<timestamp>)')
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
    sim = [f'world:={Path(args.world).resolve()}' if args.world else None, f'seed:={args.seed}',
           f'real_time_factor:={float(args.real_time_factor)}', 'noise:=false' if args.no_noise else None]
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


def stop_children(children: list[Child]) -> list[str]:
    """SIGINT in STOP_ORDER, a bounded wait each, SIGKILL if needed; returns what went wrong."""
    problems = []
    for child in sorted(children, key=lambda c: STOP_ORDER.index(c.role)):
        if child.process.poll() is None:
            child.process.send_signal(signal.SIGINT)
            try:
                child.process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                child.process.kill()
                child.process.wait()
                problems.append(f'{child.name} did not stop within {STOP_TIMEOUT:.0f} s of SIGINT and was killed')
                continue
        if child.process.returncode not in (0, -signal.SIGINT, 128 + signal.SIGINT):
            problems.append(f'{child.name} exited with code {child.process.returncode}')
    return problems


class RunMonitor:
    """Follows simulated time, distance travelled and collisions over DDS, for `--duration` and the summary."""

    def __init__(self, namespace: str) -> None:
        import rclpy
        from nav_msgs.msg import Odometry
        from rclpy.node import Node
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import UInt32

        rclpy.init(args=['--ros-args', *(['-r', f'__ns:=/{namespace.strip("/")}'] if namespace else [])],
                   signal_handler_options=SignalHandlerOptions.NO)
        self._rclpy = rclpy
        self.node = Node('bringup')
        self.sim_time = 0.0
        self.distance = 0.0
        self.collisions = 0
        self._last_xy: tuple[float, float] | None = None
        self.node.create_subscription(Clock, '/clock', self._on_clock, 10)
        self.node.create_subscription(Odometry, 'ground_truth', self._on_truth, 10)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(UInt32, 'collisions', self._on_collisions, latched)

    def _on_clock(self, msg: object) -> None:
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _on_truth(self, msg: object) -> None:
        xy = (msg.pose.pose.position.x, msg.pose.pose.position.y)
        if self._last_xy is not None:
            self.distance += math.dist(xy, self._last_xy)
        self._last_xy = xy

    def _on_collisions(self, msg: object) -> None:
        self.collisions = msg.data

    def spin_once(self, timeout: float) -> None:
        self._rclpy.spin_once(self.node, timeout_sec=timeout)

    def close(self) -> None:
        self.node.destroy_node()
        self._rclpy.try_shutdown()


def run(args: argparse.Namespace) -> int:
    stop_requested = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop_requested.set())
    monitor = RunMonitor(args.namespace)
    children: list[Child] = []
    failure = ''
    wall_start = time.monotonic()
    try:
        sim = start_child('sim', 'sim', args.sim_params, args.namespace, ready_text='sim ready')
        children.append(sim)
        if not wait_ready(sim, stop_requested):
            failure = f'sim did not become ready within {READY_TIMEOUT:.0f} s'
        if not failure and args.record is not None:
            record_args = ('-o', args.record) if args.record else ()
            recorder = start_child('record', 'record', [], args.namespace, record_args, ready_text='Recording')
            children.append(recorder)
            if not wait_ready(recorder, stop_requested):
                failure = f'record did not start within {READY_TIMEOUT:.0f} s'
        if not failure:
            children.append(start_child('behaviour', args.behaviour, args.behaviour_params, args.namespace))
            failure = supervise(children, monitor, args.duration, stop_requested)
    finally:
        problems = stop_children(children)
        for _ in range(5):  # let the last ground_truth and collision messages in
            monitor.spin_once(0.02)
        wall = time.monotonic() - wall_start
        monitor.close()
    if failure:
        problems.insert(0, failure)
    print_summary(monitor, wall, problems)
    return 1 if problems else 0


def wait_ready(child: Child, stop_requested: threading.Event) -> bool:
    deadline = time.monotonic() + READY_TIMEOUT
    while time.monotonic() < deadline and not stop_requested.is_set():
        if child.ready.wait(0.1):
            return True
        if child.process.poll() is not None:
            return False
    return stop_requested.is_set()


def supervise(children: list[Child], monitor: RunMonitor, duration: float, stop_requested: threading.Event) -> str:
    """Spin until the duration is reached or a stop is asked for ('' returned), or a child dies (its story)."""
    while not stop_requested.is_set():
        monitor.spin_once(0.05)
        for child in children:
            if child.process.poll() is not None:
                time.sleep(0.2)  # let its last lines arrive
                lines = '\n  '.join(child.tail) or '(no output)'
                return f'{child.name} exited unexpectedly with code {child.process.returncode}; last lines:\n  {lines}'
        if duration and monitor.sim_time >= duration:
            break
    return ''


def print_summary(monitor: RunMonitor, wall: float, problems: list[str]) -> None:
    speed = f'{monitor.sim_time / wall:.1f}x real time' if wall > 0 else ''
    print(f'[bringup] simulated {monitor.sim_time:.2f} s in {wall:.1f} s wall ({speed}); '
          f'distance travelled {monitor.distance:.3f} m; collisions {monitor.collisions}', flush=True)
    for problem in problems:
        print(f'[bringup] error: {problem}', file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> None:
    sys.exit(run(parse_args(sys.argv[1:] if argv is None else argv)))


if __name__ == '__main__':
    main()
