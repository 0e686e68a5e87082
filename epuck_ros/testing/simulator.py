"""A lockstep simulator on a private ROS domain, driven from a test: start it paused, let the test's own nodes
connect, run simulated time forward, read each robot's ground truth and contacts, stop it whatever happens.

The `sim` runs in its own process (as in production); the test process talks to it through a node in a private
rclpy context, spun in a background thread, so the test's code stays plain and blocking.
"""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import AbstractContextManager
from pathlib import Path
from collections.abc import Callable, Mapping, Sequence
from typing import IO, Any

from epuck_ros.conversions import seconds_from_stamp, yaw_from_quaternion
from epuck_ros.integrity import STATUS_TOPIC, Integrity, integrity_from

POLL = 0.05
"""Wall seconds between two looks at the graph or the simulator's parameters while waiting."""
LATEST_TIME = 1e9
"""The latest simulated time `run_until` can reach: the simulator's `pause_at` range."""
STOP_TIMEOUT = 10.0
"""Wall seconds the simulator has to end after Ctrl-C before it is killed."""


class SimulatorUnderTest:
    """`sim` in lockstep, paused, on a private domain; `env` is the environment for the test's own processes."""

    def __init__(self, world: str | os.PathLike | None = None, robots: int = 0, seed: int = 0,
                 log_dir: Path | None = None, start_timeout: float = 30.0, env: Mapping[str, str] | None = None,
                 **parameters: object) -> None:
        """`parameters` go to `sim` (`-p name:=value`); `env` adds to the environment of the simulator and of
        `self.env` (e.g. another ROS_AUTOMATIC_DISCOVERY_RANGE; LOCALHOST by default). A misuse is a TypeError or
        ValueError naming it, before anything starts."""
        from epuck_ros.world import default_world, load_world, place_robots
        for name, value in (('robots', robots), ('seed', seed)):
            if not isinstance(value, int) or isinstance(value, bool):
                raise TypeError(f'epuck_sim: {name} must be an int, got {value!r}')
            if value < 0:
                raise ValueError(f'epuck_sim: {name} must be 0 or more, got {value}')
        layout = load_world(str(world)) if world else default_world()
        if robots > 0:
            layout = place_robots(layout, robots, seed)
        self.names: tuple[str, ...] = layout.names
        """The robots' names, in the simulator's order."""
        self.start_poses = {robot.name: robot.pose for robot in layout.robots}
        from epuck_ros.ros.dds_profile import PROFILES_FILE, PROFILES_VARIABLE, use_package_profile
        use_package_profile()   # this process's participant (made below) announces itself every 0.5 s, not 3 s
        self.domain, self._domain_claim = claim_free_domain()
        self.env = {**os.environ, 'ROS_DOMAIN_ID': str(self.domain), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                    PROFILES_VARIABLE: os.environ.get(PROFILES_VARIABLE, str(PROFILES_FILE)),
                    'PATH': os.pathsep.join([str(Path(sys.executable).parent), os.environ.get('PATH', os.defpath)]),
                    **(env or {})}
        """The environment for the test's own processes: the simulator's domain, discovery on this machine, the
        package's DDS profile (a node that misses the simulator's first announcement hears the next 0.5 s later,
        not 3 s: most of the time a test took to see its node connected), and this interpreter's scripts first on
        PATH: `forward` is the package's next to this Python, also under `.venv/bin/python -m pytest` with the venv
        not activated (it was `FileNotFoundError: 'forward'`)."""
        self._lock = threading.Lock()
        self._clock = 0.0
        self._truth: dict[str, tuple[float, float, float, float]] = {}
        self._swarm = None
        """Which robots swarm controllers declared they drive (ros/swarm_ports.DeclaredRobots), with several."""
        self._controlled: set[str] = set()
        """The robots `wait_for_controller` saw driven: the first `run_until` waits until the simulator sees them."""
        self._context = None
        self._stopped = False
        self._thread: threading.Thread | None = None
        self.process: subprocess.Popen | None = None
        self.log_path = Path(log_dir or tempfile.mkdtemp(prefix='epuck_sim_')) / f'sim-domain{self.domain}.log'
        self._log: IO | None = None
        try:
            self._start_process(world, robots, seed, parameters)
            self._connect(start_timeout)
        except BaseException:
            self.stop()
            raise

    # --- the test's API -----------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """The simulated time of the last step (s)."""
        with self._lock:
            return self._clock

    def wait_for_controller(self, robot: str | int | None = None, timeout: float = 30.0) -> None:
        """Return once a publisher on the robot's `wheel_cmd` or `cmd_vel` is matched, or a swarm controller
        (`swarm/command`) declared it drives the robot (None: every robot's)."""
        self._check_running()
        robots = self.names if robot is None else (self._name(robot),)
        topics = {name: [self._topic(name, 'wheel_cmd'), self._topic(name, 'cmd_vel')] for name in robots}
        swarm = self._swarm.controllers if self._swarm is not None else lambda name: []
        self._wait(lambda: all(any(self._node.count_publishers(t) for t in topics[name]) or swarm(name)
                               for name in robots),
                   timeout, f'no controller publishes the commands of {", ".join(robots)}')
        self._controlled.update(robots)

    def run_until(self, t: float, timeout: float = 120.0) -> float:
        """Run simulated time forward to the first step at or after `t` seconds and pause there; returns that time
        (the current one if it is `t` already).

        Returns once the simulator has paused and every robot's ground truth of that step has arrived. A `t` that is
        no finite number, is in the past or beyond LATEST_TIME is a ValueError, and nothing happens."""
        from rclpy.parameter import Parameter
        self._check_running()
        if not isinstance(t, (int, float)) or isinstance(t, bool) or not math.isfinite(t):
            raise ValueError(f'run_until: t must be a finite number of simulated seconds, got {t!r}')
        now = self.time
        if t < now - 1e-9:
            raise ValueError(f'run_until({t:g}): the simulation is at t={now:.3f} s already; time only runs forward')
        if t > LATEST_TIME:
            raise ValueError(f'run_until({t:g}): beyond the latest time the simulator can pause at ({LATEST_TIME:g} s)')
        if t <= now + 1e-9:
            return now
        # Before the first step: the controllers seen here, which the simulator may not have matched yet.
        first = [Parameter('lockstep_controllers', value=len(self._controlled))] if now == 0.0 else []
        result = self._call(self._parameters.set_parameters_atomically(   # all of them, or none
            first + [Parameter('pause_at', value=float(t)), Parameter('paused', value=False)]), timeout)
        if not result.result.successful:
            raise ValueError(f'the simulator refused to run to t={t}: {result.result.reason}')
        self._wait(lambda: self.time >= t - 1e-9, timeout, f'simulated time did not reach {t} s')
        self._wait(self._paused, timeout, f'the simulator did not pause at {t} s')
        now = self.time
        self._wait(lambda: all(self._truth.get(name, (-1.0,))[0] >= now - 1e-9 for name in self.names), timeout,
                   f'the ground truth of t={now} s did not arrive')
        return now

    def ground_truth(self, robot: str | int | None = None) -> tuple[float, float, float]:
        """(x, y, yaw) of the robot in the world (None: the first robot), as of the last step."""
        self._check_running()
        name = self._name(robot)
        with self._lock:
            stamped = self._truth.get(name)
        return self.start_poses[name] if stamped is None else stamped[1:]

    def contacts(self, robot: str | int | None = None, timeout: float = 30.0) -> int:
        """The number of the robot's contacts with obstacles or robots so far (None: the first robot), from its
        latched `collisions`."""
        from std_msgs.msg import UInt32
        self._check_running()
        name = self._name(robot)
        return self._latest(UInt32, self._topic(name, 'collisions'), timeout, f'no collision count of {name}').data

    @property
    def reproducible(self) -> bool:
        """Whether the run so far is reproducible: every step answered, by name, by every driven robot's controller
        (the simulator's `lockstep_status`); `integrity()` says why not."""
        return self.integrity().reproducible

    def integrity(self, timeout: float = 30.0) -> Integrity:
        """The simulator's verdict on the run so far (epuck_ros/integrity.py): reproducible, or why not and since
        when."""
        from diagnostic_msgs.msg import DiagnosticStatus
        self._check_running()
        status = self._latest(DiagnosticStatus, '/' + STATUS_TOPIC, timeout, 'no lockstep_status from the simulator')
        return integrity_from(status.message, {value.key: value.value for value in status.values})

    def _latest(self, msg_type: type, topic: str, timeout: float, what: str) -> Any:
        """The latest message of a latched topic, from a new subscription: the simulator publishes such a topic after
        the step's `/clock`, so a subscription kept from the start could still have it on its way."""
        from epuck_ros.ros.qos import LATCHED
        received: list[Any] = []
        subscription = self._node.create_subscription(msg_type, topic, received.append, LATCHED)
        try:
            self._wait(lambda: bool(received), timeout, what)
        finally:
            self._node.destroy_subscription(subscription)
        return received[-1]

    def output(self) -> str:
        """What the simulator printed so far."""
        if self._log is not None:
            self._log.flush()
        return self.log_path.read_text() if self.log_path.exists() else ''

    def stop(self) -> None:
        """Stop the simulator (Ctrl-C, then SIGKILL after STOP_TIMEOUT) and the test's node; safe to call twice."""
        from epuck_ros.bringup.processes import interrupt
        self._stopped = True
        if self._context is not None:
            self._context.try_shutdown()
            if self._thread is not None:
                self._thread.join(timeout=STOP_TIMEOUT)
            self._context = None
        if self.process is not None:
            interrupt(self.process, STOP_TIMEOUT)
        if self._log is not None:
            self._log.close()
            self._log = None
        if self._domain_claim is not None:
            self._domain_claim.__exit__(None, None, None)
            self._domain_claim = None

    # --- inside ------------------------------------------------------------------------------------------

    def _start_process(self, world: str | os.PathLike | None, robots: int, seed: int,
                       parameters: dict[str, object]) -> None:
        # discovery_window 0: the domain is claimed for this simulator alone, no other can be on it
        values: dict[str, object] = {'lockstep': True, 'paused': True, 'real_time_factor': 0.0, 'seed': seed,
                                     'robots': robots, 'discovery_window': 0.0, **parameters}
        if world:
            values['world'] = str(Path(world).resolve())
        args = ['--ros-args'] + [arg for name, value in values.items() for arg in ('-p', f'{name}:={_text(value)}')]
        self._log = open(self.log_path, 'w')
        self.process = subprocess.Popen([sys.executable, '-m', 'epuck_ros.nodes.sim_node', *args],
                                        env=dict(self.env, PYTHONUNBUFFERED='1'), stdout=self._log,
                                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)

    def _connect(self, timeout: float) -> None:
        import rclpy
        from nav_msgs.msg import Odometry
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.parameter_client import AsyncParameterClient
        from rosgraph_msgs.msg import Clock

        self._context = Context()
        rclpy.init(context=self._context, domain_id=self.domain)
        self._node = Node(f'epuck_sim_fixture_{os.getpid()}', context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._node.create_subscription(Clock, '/clock', self._on_clock, 10)
        for name in self.names:
            self._node.create_subscription(Odometry, self._topic(name, 'ground_truth'),
                                           lambda msg, name=name: self._on_truth(name, msg), 10)
        if len(self.names) > 1:   # a swarm controller (`avoid --robots all`) names the robots it drives
            from epuck_ros.ros.swarm_ports import DeclaredRobots
            self._swarm = DeclaredRobots(self._node)
        self._parameters = AsyncParameterClient(self._node, 'sim')
        self._thread = threading.Thread(target=self._spin, name='epuck_sim_fixture', daemon=True)
        self._thread.start()
        truth_topics = [self._topic(name, 'ground_truth') for name in self.names]
        self._wait(lambda: self._parameters.services_are_ready() and all(
            self._node.count_publishers(topic) for topic in truth_topics), timeout, 'the simulator did not come up')

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException
        try:
            while self._context is not None and self._context.ok():
                self._executor.spin_once(timeout_sec=POLL)
        except ExternalShutdownException:
            pass

    def _on_clock(self, msg: Any) -> None:
        with self._lock:
            self._clock = seconds_from_stamp(msg.clock.sec, msg.clock.nanosec)

    def _on_truth(self, name: str, msg: Any) -> None:
        q = msg.pose.pose.orientation
        yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
        stamp = seconds_from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        with self._lock:
            self._truth[name] = (stamp, msg.pose.pose.position.x, msg.pose.pose.position.y, yaw)

    def _paused(self) -> bool:
        result = self._call(self._parameters.get_parameters(['paused']), STOP_TIMEOUT)
        return bool(result.values and result.values[0].bool_value)

    def _check_running(self) -> None:
        if self._stopped:
            raise RuntimeError('epuck_sim: this simulator was stopped (sim.stop()); start another with epuck_sim()')

    def _name(self, robot: str | int | None) -> str:
        """The name of `robot` (a name, an index, or None: the first robot); KeyError naming the robots if none."""
        if robot is None:
            return self.names[0]
        if isinstance(robot, int) and not isinstance(robot, bool):
            if not -len(self.names) <= robot < len(self.names):
                raise KeyError(f'no robot {robot}: there are {len(self.names)} ({", ".join(self.names)}), from 0')
            return self.names[robot]
        if robot not in self.names:
            raise KeyError(f'no robot {robot!r}: the robots are {", ".join(self.names)}')
        return robot

    def _topic(self, name: str, topic: str) -> str:
        from epuck_ros.ros.robot_ports import topic_prefix
        return '/' + topic_prefix(name, len(self.names) > 1) + topic

    def _wait(self, condition: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if self.process is not None and self.process.poll() is not None:
                raise RuntimeError(f'{what}: the simulator ended (exit code {self.process.returncode}):\n'
                                   f'{self.output()[-2000:]}')
            if time.monotonic() > deadline:
                raise TimeoutError(f'{what} within {timeout:g} s (wall)')
            time.sleep(POLL)

    def _call(self, future: Any, timeout: float) -> Any:
        """The result of an rclpy future that the background executor completes."""
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise TimeoutError(f'the simulator did not answer within {timeout:g} s (wall)')
        return future.result()


DOMAIN_RANGE_VARIABLE = 'EPUCK_ROS_DOMAIN_RANGE'
"""`FIRST-LAST` (inclusive): the ROS domains the fixture's simulators and this package's own test runs claim (a CI
that shares a machine gives each job a range of its own). Unset: 1-100, `domain_coordinator`'s range."""
DEFAULT_DOMAINS = range(1, 101)
MAX_DOMAIN = 232
"""The highest ROS_DOMAIN_ID (ROS 2's limit on Linux: its ports must stay below 65536)."""


class NoFreeDomain(RuntimeError):
    """Every domain of the range is claimed by another test run or simulator on this machine."""


def domain_range() -> range:
    """The domains to claim from: EPUCK_ROS_DOMAIN_RANGE, or DEFAULT_DOMAINS. A malformed value is a ValueError
    naming the variable."""
    text = os.environ.get(DOMAIN_RANGE_VARIABLE, '').strip()
    if not text:
        return DEFAULT_DOMAINS
    match = re.fullmatch(r'([0-9]{1,3})\s*-\s*([0-9]{1,3})', text)
    if match is None or not int(match[1]) <= int(match[2]) <= MAX_DOMAIN:
        raise ValueError(f'{DOMAIN_RANGE_VARIABLE}={text!r}: expected FIRST-LAST, ROS domain IDs from 0 to '
                         f'{MAX_DOMAIN} with FIRST <= LAST (e.g. 20-39)')
    return range(int(match[1]), int(match[2]) + 1)


def claim_domain(preferred: Sequence[int] = (), avoid: str = '') -> tuple[int, AbstractContextManager[int]]:
    """A ROS domain no other claimant on this machine holds: one of `preferred`, else one of `domain_range()` (never
    `avoid`), and its claim (exit it to free the domain). Claimed with `domain_coordinator`, as ROS 2's own tests
    claim theirs. NoFreeDomain, naming the range, when every one is held."""
    import domain_coordinator   # only when a test asks for a simulator: the plugin's import stays free
    domains = [domain for domain in domain_range() if str(domain) != avoid]
    first = os.getpid() % len(domains) if domains else 0   # processes started together try different ones first
    candidates = iter([*preferred, *domains[first:], *domains[:first]])
    where = (f'{DOMAIN_RANGE_VARIABLE}={os.environ[DOMAIN_RANGE_VARIABLE].strip()}'
             if os.environ.get(DOMAIN_RANGE_VARIABLE, '').strip() else
             f'{DEFAULT_DOMAINS[0]}-{DEFAULT_DOMAINS[-1]} (set {DOMAIN_RANGE_VARIABLE}=FIRST-LAST for another range)')
    exhausted = NoFreeDomain(f'no free ROS domain in {where}{f" other than {avoid}" if avoid else ""}: each is '
                             'claimed by another test run or simulator on this machine; widen the range or wait')

    def pick() -> int:
        try:
            return next(candidates)
        except StopIteration:
            raise exhausted from None

    claim = domain_coordinator.domain_id(pick)
    try:
        return claim.__enter__(), claim
    except NoFreeDomain:
        raise
    except RuntimeError:   # domain_coordinator gives up after 100 attempts
        raise exhausted from None


def claim_free_domain() -> tuple[int, AbstractContextManager[int]]:
    """The simulator's domain (`claim_domain`): never this process's own ROS_DOMAIN_ID, which its own nodes (or a
    user's robot) may be using unclaimed."""
    return claim_domain(avoid=os.environ.get('ROS_DOMAIN_ID', ''))


def _text(value: object) -> str:
    """A parameter value as `-p name:=value` wants it."""
    return str(value).lower() if isinstance(value, bool) else str(value)
