"""Shared fixtures: DDS kept on localhost, a private ROS domain per test run, real node processes.

Every ROS process a test starts goes through `launch`, which stops it (SIGINT, a bounded wait,
then SIGKILL) when the test ends, so no process outlives its test.
"""
from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from epuck_ros.bringup.processes import interrupt

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

_DOMAIN_LOCK_DIR = Path('/tmp/epuck_ros_test_domains')


def _claim_domain_id() -> int:
    """Lock a ROS_DOMAIN_ID no other test run on this machine holds; the lock lasts as long as this process."""
    _DOMAIN_LOCK_DIR.mkdir(exist_ok=True)
    start = os.getpid() % 90
    for offset in range(90):
        domain = 10 + (start + offset) % 90
        handle = open(_DOMAIN_LOCK_DIR / f'{domain}.lock', 'w')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _claim_domain_id.handle = handle  # type: ignore[attr-defined]  # keep the lock alive
        return domain
    raise RuntimeError('no free ROS_DOMAIN_ID between 10 and 99 for this test run')


os.environ['ROS_DOMAIN_ID'] = str(_claim_domain_id())

BIN_DIR = Path(sys.executable).parent


class NodeProcess:
    """One executable of the package running in its own process, its output kept in a log file."""

    def __init__(self, name: str, args: list[str], log_path: Path) -> None:
        self.name = name
        self.log_path = log_path
        self._log = open(log_path, 'w')
        self.proc = subprocess.Popen(
            [str(BIN_DIR / name), *args], stdout=self._log, stderr=subprocess.STDOUT,
            env=dict(os.environ, PYTHONUNBUFFERED='1'), start_new_session=True)

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
    """Start a package executable: `launch('sim', '--ros-args', '-p', 'seed:=3')`; stopped after the test."""
    started: list[NodeProcess] = []

    def start(name: str, *args: str) -> NodeProcess:
        process = NodeProcess(name, list(args), tmp_path / f'{name}-{len(started)}.log')
        started.append(process)
        return process

    yield start
    for process in reversed(started):
        process.stop()


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
    """(pid, command line) of every other process running with this test run's ROS_DOMAIN_ID."""
    marker = f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}'.encode()
    found = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = (entry / 'environ').read_bytes().split(b'\0')
            cmdline = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
        except OSError:
            continue
        if marker in environ:
            found.append((int(entry.name), cmdline))
    return found
