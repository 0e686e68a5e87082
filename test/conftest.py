"""Shared fixtures: DDS kept on localhost, a private ROS domain per test run, real node processes.

Every ROS process a test starts goes through `launch`, which stops it (SIGINT, a bounded wait,
then SIGKILL) when the test ends, so no process outlives its test.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from epuck_ros.bringup.monitor import REQUEST_RETRY
from epuck_ros.bringup.processes import interrupt
from epuck_ros.testing.simulator import NoFreeDomain, claim_domain

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    # pytest-xdist's workers start with Ctrl-C ignored, and every process a test starts would inherit that: a sweep,
    # an evolve or a README command a test interrupts ran on (until some test's rclpy.init installed a handler).
    signal.signal(signal.SIGINT, signal.default_int_handler)


EVERY_MESSAGE = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
"""A reader that gets every step's message, in order, however far behind it falls (as a recorder does): the simulator
waits for it (ros/ack_window.py). A KEEP_LAST reader of any depth, reliable or not, is not waited for and skips
samples when the simulator runs ahead of it under load: with a busy loop on each core a depth-2000 reader of
ground_truth had 245 of the first 988 steps, in holes; in a repeat, a KEEP_ALL reader beside it had every step."""


def _claim_domain_id() -> tuple[int, str]:
    """The ROS_DOMAIN_ID of this test run and how it was chosen, claimed with `domain_coordinator` (as ROS 2's own
    tests claim theirs) for as long as this process lives: the user's own if set and no other test run holds it,
    else one of EPUCK_ROS_DOMAIN_RANGE (default 1-100) that no other test run on this machine holds."""
    wanted = os.environ.get('ROS_DOMAIN_ID', '')
    try:
        domain, claim = claim_domain(preferred=[int(wanted)] if wanted.isdigit() else [])
    except (NoFreeDomain, ValueError) as error:
        pytest.exit(f'cannot claim a ROS domain for this test run: {error}', returncode=pytest.ExitCode.USAGE_ERROR)
    _claim_domain_id.claim = claim  # type: ignore[attr-defined]  # keep the claim alive (released at exit)
    if wanted.isdigit() and domain == int(wanted):
        return domain, 'set by you'
    how = f'your ROS_DOMAIN_ID={wanted} is in use by another test run' if wanted else 'ROS_DOMAIN_ID unset'
    return domain, f'{how}: a free one was claimed'


_DOMAIN, _DOMAIN_CHOICE = _claim_domain_id()
os.environ['ROS_DOMAIN_ID'] = str(_DOMAIN)
os.environ['EPUCK_ROS_TEST_RUN'] = str(os.getpid())
"""Inherited by every process this test run starts, so it can tell them from anyone else's on the same domain."""


def pytest_configure(config: pytest.Config) -> None:
    """The package's own pytest plugin (`epuck_sim`), also where its `pytest11` entry point is not installed."""
    if not config.pluginmanager.has_plugin('epuck_ros'):
        config.pluginmanager.import_plugin('epuck_ros.testing.plugin')


def pytest_report_header() -> str:
    return f'ROS_DOMAIN_ID={_DOMAIN} ({_DOMAIN_CHOICE}), ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST'


LONGEST_FILES = ('test_bringup.py', 'test_readme.py', 'test_same_run.py', 'test_webots.py', 'test_sim_node.py',
                 'test_sweep_hostile.py', 'test_experiments.py', 'test_bag_fuzz.py', 'test_bag_on_demand.py',
                 'test_bag_record.py', 'test_senses_ros.py', 'test_bag_headless.py', 'test_multi_robot_nodes.py',
                 'test_multi_controller.py', 'test_bag_readers.py', 'test_behaviour_nodes.py', 'test_bag_shapes.py',
                 'test_view_node.py', 'test_bag_cli.py', 'test_lint.py', 'test_evolution.py')
"""The test files that take longest (`pytest --durations=0`, summed per file), longest first."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The longest files first, then the others by their number of tests (pytest-xdist's own order), each file's
    tests in their own order: scripts/test.sh's processes take files in this order (`--dist loadfile
    --no-loadscope-reorder`), and a long file taken last would keep one of them busy alone at the end."""
    rank = {name: index for index, name in enumerate(LONGEST_FILES)}
    counts = Counter(item.path.name for item in items)
    items.sort(key=lambda item: (rank.get(item.path.name, len(rank)), -counts[item.path.name], item.path.name))


def _ctrl_c_disposition() -> tuple[bool, bool]:
    """Whether SIGINT is ignored and whether it is blocked in this process's main thread, as the kernel holds them
    (what every process a test starts inherits: a child that inherits either never sees Ctrl-C)."""
    fields = dict(line.split(':', 1) for line in Path('/proc/self/status').read_text().splitlines() if ':' in line)
    bit = 1 << (signal.SIGINT - 1)
    return bool(int(fields['SigIgn'], 16) & bit), bool(int(fields['SigBlk'], 16) & bit)


@pytest.fixture(autouse=True)
def _ctrl_c_left_as_it_was() -> Iterator[None]:
    """No test leaves Ctrl-C ignored or blocked for the tests after it: a sweep, an evolve, a README command
    interrupted by a later test in the same process ignored the interruption and ran on (a loaded suite run)."""
    before = _ctrl_c_disposition()
    yield
    assert _ctrl_c_disposition() == before, 'this test left SIGINT ignored or blocked (SigIgn, SigBlk) in the process'


BIN_DIR = Path(sys.executable).parent


class NodeProcess:
    """One executable of the package running in its own process, its output kept in a log file."""

    def __init__(self, name: str, args: list[str], log_path: Path, stdin: int | None = None) -> None:
        """`stdin=subprocess.PIPE` gives the test a pipe to `type` into (teleop's keys)."""
        self.name = name
        self.log_path = log_path
        self._log = open(log_path, 'w')
        self.proc = subprocess.Popen(
            [str(BIN_DIR / name), *args], stdin=stdin, stdout=self._log, stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONUNBUFFERED='1'), start_new_session=True)

    def type(self, keys: bytes) -> None:
        """Write `keys` to the process's stdin pipe."""
        self.proc.stdin.write(keys)
        self.proc.stdin.flush()

    def output(self) -> str:
        self._log.flush()
        return self.log_path.read_text()

    def wait_for_output(self, text: str, timeout: float = 15.0) -> None:
        """Block until `text` appears in the process output; fail with the output if it does not."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.output():
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.05)
        raise AssertionError(f'{self.name} did not print {text!r}; output:\n{self.output()}')

    def stop(self, timeout: float = 10.0) -> int:
        """SIGINT, then SIGKILL after `timeout`; returns the exit code."""
        interrupt(self.proc, timeout)
        self._log.close()
        return self.proc.returncode


@pytest.fixture
def launch(tmp_path: Path) -> Iterator[Callable[..., NodeProcess]]:
    """Start a package executable (`'sim', '--ros-args', '-p', 'seed:=3'`); stopped after the test."""
    started: list[NodeProcess] = []

    def start(name: str, *args: str, stdin: int | None = None) -> NodeProcess:
        process = NodeProcess(name, list(args), tmp_path / f'{name}-{len(started)}.log', stdin)
        started.append(process)
        return process

    yield start
    for process in reversed(started):
        process.stop()


ALONE_ON_THE_DOMAIN = {'discovery_window': 0.0}
"""Simulator parameters for a test's own simulator: each test run claims its ROS domain, so no other simulator can be
there, and the simulator need not look for one before its first step (as the epuck_sim fixture does)."""


def ros_args(params: dict[str, object]) -> list[str]:
    """`--ros-args -p name:=value ...` for a parameter dict."""
    args = ['--ros-args']
    for name, value in params.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        args += ['-p', f'{name}:={text}']
    return args


@pytest.fixture(scope='session')
def rclpy_context() -> Iterator[None]:
    import rclpy
    rclpy.init()
    yield
    rclpy.try_shutdown()


class RosTestNode:
    """An rclpy node inside the test process, with helpers to spin until something happened."""

    def __init__(self) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        self.node = Node(f'test_node_{os.getpid()}')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def collect(self, msg_type: type, topic: str, qos: object = 10) -> list:
        """Subscribe and return the list the received messages are appended to."""
        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    def spin_until(self, predicate: Callable[[], bool], timeout: float = 20.0, what: str = 'condition') -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return
            self.executor.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out after {timeout} s waiting for {what}')

    def wait_for_simulator(self, namespace: str = '', timeout: float = 30.0) -> None:
        """Wait until a simulator is up, from the graph: its `step` service is there, made after every robot's
        topics and the latched world (what the simulator logs as 'sim ready' comes just after)."""
        from std_srvs.srv import Trigger
        client = self.node.create_client(Trigger, f'{namespace}/step')
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise AssertionError(f'timed out after {timeout} s waiting for the simulator ({namespace}/step)')
        finally:
            self.node.destroy_client(client)

    def watch_log(self) -> list[str]:
        """The messages every node logs from now on, as /rosout carries them (for a warning that is the product)."""
        from rcl_interfaces.msg import Log
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        messages: list[str] = []
        rosout = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)   # rclpy's own /rosout profile
        self.node.create_subscription(Log, '/rosout', lambda msg: messages.append(msg.msg), rosout)
        return messages

    def wait_for_log(self, messages: list[str], text: str, timeout: float = 20.0) -> None:
        """Spin until one of `messages` (from `watch_log`) contains `text`."""
        self.spin_until(lambda: any(text in message for message in messages), timeout, f'a log message with {text!r}')

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def destroy(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def test_node(rclpy_context: None) -> Iterator[RosTestNode]:
    node = RosTestNode()
    yield node
    node.destroy()


def processes_in_this_domain() -> list[tuple[int, str]]:
    """(pid, command line) of every other ROS process this test run started (its ROS_DOMAIN_ID and run marker)."""
    markers = (f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}'.encode(),
               f'EPUCK_ROS_TEST_RUN={os.environ["EPUCK_ROS_TEST_RUN"]}'.encode())
    found = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = (entry / 'environ').read_bytes().split(b'\0')
            cmdline = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
        except OSError:
            continue
        if all(marker in environ for marker in markers):
            found.append((int(entry.name), cmdline))
    return found


def set_sim_parameter(test_node: object, sim: object, name: str, value: object) -> None:
    """Set a parameter of the running `sim` process (failing at once, with its output, if it ended)."""
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    client = AsyncParameterClient(test_node.node, 'sim')
    test_node.spin_until(lambda: client.services_are_ready() or sim.proc.poll() is not None, timeout=60.0,
                         what='the sim parameter services')
    assert sim.proc.poll() is None, sim.output()
    # Asked again every REQUEST_RETRY, as bringup does (setting a parameter twice is harmless): a request to services
    # just discovered can go unanswered, the response's way back not matched yet (a loaded suite run waited 60 s).
    deadline = time.monotonic() + 60.0
    while True:
        future = client.set_parameters([Parameter(name, value=value)])
        retry = min(time.monotonic() + REQUEST_RETRY, deadline)
        while not future.done() and sim.proc.poll() is None and time.monotonic() < retry:
            test_node.executor.spin_once(timeout_sec=0.05)
        if future.done() or sim.proc.poll() is not None or time.monotonic() >= deadline:
            break
    assert future.done(), f'sim did not accept {name} in 60 s:\n{sim.output()}'
    assert all(result.successful for result in future.result().results)
