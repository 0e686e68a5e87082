"""teleop as a real process: keys from a pipe become Twists on the chosen robot's cmd_vel; leaving stops the robot."""
from __future__ import annotations

import functools
import os
import signal
import subprocess
from collections.abc import Callable

import pytest
from geometry_msgs.msg import Twist

from conftest import BIN_DIR, NodeProcess
from epuck_ros.nodes.teleop_node import MAX_SPEED, MAX_TURN, SPEED_STEP, Teleop, read_keys


@pytest.fixture
def teleop(launch) -> Callable[..., NodeProcess]:
    """Start `teleop` with its stdin a pipe the test types into (stopped, by pid, when the test ends)."""
    return functools.partial(launch, 'teleop', stdin=subprocess.PIPE)


def _last(received: list[Twist]) -> tuple[float, float] | None:
    return (received[-1].linear.x, received[-1].angular.z) if received else None


def test_keys_set_motions_and_speeds() -> None:
    keys = Teleop(speed=0.1, turn=1.5)
    assert keys.command == (0.0, 0.0)
    assert keys.press('w') and keys.command == (0.1, 0.0)
    assert keys.press('left') and keys.command == (0.0, 1.5)
    assert keys.press('q') and keys.command == pytest.approx((0.0, 1.5 * SPEED_STEP))
    assert keys.press('s') and keys.command == pytest.approx((-0.1 * SPEED_STEP, 0.0))
    assert keys.press(' ') and keys.command == (0.0, 0.0)
    assert not keys.press('?')
    chars = iter('w\x1b[Dx\nz\x1b[A')
    assert list(read_keys(lambda: next(chars, ''))) == ['w', 'left', 'x', 'z', 'up']


def test_help_describes_keys_options_and_parameters() -> None:
    result = subprocess.run([str(BIN_DIR / 'teleop'), '--help'], capture_output=True, text=True, timeout=30)
    assert result.returncode == 0
    for text in ('--robot', 'speed', 'turn', 'repeat_rate', 'example'):
        assert text in result.stdout


def test_keys_drive_the_chosen_robot_and_end_of_input_stops_it(test_node, teleop) -> None:
    received = test_node.collect(Twist, '/epuck3/cmd_vel', 100)
    other = test_node.collect(Twist, '/cmd_vel', 100)
    process = teleop('--robot', 'epuck3')
    process.type(b'w')  # held commands are re-sent (repeat_rate), so nothing depends on when DDS matched
    test_node.spin_until(lambda: _last(received) == (0.1, 0.0), what='forward Twist', timeout=60)
    process.type(b'\x1b[D')  # left arrow
    test_node.spin_until(lambda: _last(received) == (0.0, 1.5), what='left turn Twist', timeout=60)
    process.type(b'q')
    test_node.spin_until(lambda: _last(received) == pytest.approx((0.0, 1.5 * SPEED_STEP)),
                         what='faster turn', timeout=60)
    process.proc.stdin.close()
    assert process.proc.wait(timeout=30) == 0
    test_node.spin_until(lambda: _last(received) == (0.0, 0.0), what='the stop sent on exit', timeout=60)
    assert f'turn {1.5 * SPEED_STEP:.2f} rad/s' in process.output()
    assert other == []


def test_interrupt_stops_the_robot(test_node, teleop) -> None:
    received = test_node.collect(Twist, '/cmd_vel', 100)
    process = teleop('--ros-args', '-p', 'speed:=0.05')
    process.type(b'w')
    test_node.spin_until(lambda: _last(received) == (0.05, 0.0),
                         what='forward Twist at the speed parameter', timeout=60)
    process.proc.send_signal(signal.SIGINT)
    assert process.proc.wait(timeout=30) == 0
    test_node.spin_until(lambda: _last(received) == (0.0, 0.0), what='the stop sent on Ctrl-C', timeout=60)
    assert 'stopped' in process.output()


def test_ctrl_c_while_stopping_after_the_input_ended_leaves_cleanly(launch) -> None:
    """Its input empty (EOF at once), teleop stops the robot as soon as it printed its first line, waiting for
    subscribers to show until FOREIGN_DISCOVERY_WINDOW after its start; a Ctrl-C then was a traceback and an abort
    (exit -6, seen in test_readme). Now a clean exit 0."""
    process = launch('teleop', stdin=subprocess.DEVNULL)
    process.wait_for_output('speed ')
    process.proc.send_signal(signal.SIGINT)
    assert process.proc.wait(timeout=30) == 0, process.output()
    assert 'Traceback' not in process.output()


def test_q_stops_at_the_robots_limits_and_the_stop_is_always_zero() -> None:
    """Key q raised the speed to 0.133 m/s, above the e-puck's 0.126; 8,000 of them overflowed it to inf, and the stop
    on exit (0 x inf) became NaN, which the simulator refuses: with cmd_timeout 0 the robot drove on at full speed."""
    keys = Teleop(speed=0.1, turn=1.5)
    for _ in range(8000):
        keys.press('q')
    assert (keys.speed, keys.turn) == (MAX_SPEED, MAX_TURN) == pytest.approx((6.28 * 0.02, 2 * 6.28 * 0.02 / 0.052))
    assert keys.press('w') and keys.command == (MAX_SPEED, 0.0)
    assert "(the e-puck's top speed)" in keys.describe()
    assert keys.press(' ') and keys.command == (0.0, 0.0)
    assert Teleop(speed=1.0, turn=20.0).speed == MAX_SPEED
    for _ in range(8000):
        keys.press('z')
    assert keys.press('w') and keys.command[1] == 0.0 and keys.command[0] >= 0.0


def test_a_bad_robot_name_is_one_line_and_exit_2() -> None:
    result = subprocess.run([str(BIN_DIR / 'teleop'), '--robot', 'a b'], capture_output=True, text=True, timeout=30,
                            stdin=subprocess.DEVNULL)
    assert result.returncode == 2 and "'a b' is not a robot name" in result.stderr
    assert 'Traceback' not in result.stderr + result.stdout


def test_closed_stdin_stops_the_robot_and_leaves_cleanly(test_node, tmp_path) -> None:
    received = test_node.collect(Twist, '/cmd_vel', 100)
    log = tmp_path / 'teleop.log'
    with open(log, 'w') as out:
        process = subprocess.Popen(f'exec {BIN_DIR / "teleop"} <&-', shell=True, stdout=out, stderr=subprocess.STDOUT,
                                   env=dict(os.environ, PYTHONUNBUFFERED='1'))
    try:
        assert process.wait(timeout=60) == 0, log.read_text()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert 'standard input is closed' in log.read_text() and 'Traceback' not in log.read_text()
    test_node.spin_until(lambda: _last(received) == (0.0, 0.0), what='the stop sent on leaving', timeout=60)
