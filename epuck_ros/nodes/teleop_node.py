"""`teleop`: drive a robot from the terminal, for those who cannot install teleop_twist_keyboard (pip only).

Keys set a motion that lasts until the next key, as in teleop_twist_keyboard; the command is re-sent
`repeat_rate` times a second so that the simulator's `cmd_timeout` does not stop a robot that should keep going.
On exit (Ctrl-C, end of input, SIGTERM) a zero Twist is sent and waited for, so the robot stops.

Input is read one character at a time: from a terminal in cbreak mode (no Enter needed), or from a pipe (tests,
scripts: `printf 'w' | teleop`), where end of input quits.
"""
from __future__ import annotations

import argparse
import os
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from epuck_ros.model import RobotModel
from epuck_ros.ros.dds_profile import use_package_profile
from epuck_ros.ros.matching import FOREIGN_DISCOVERY_WINDOW, wait_until_matched
from epuck_ros.ros.params import ParamSpec, Usage, declare_parameters, prepare_arguments, user_arguments
from epuck_ros.ros.spinning import interrupt_on_signals
from epuck_ros.world import ROBOT_NAME, ROBOT_NAME_MAX

SPEED_STEP = 1.1
"""Factor by which q / z change both speeds (teleop_twist_keyboard's)."""
_MODEL = RobotModel()
MAX_SPEED = _MODEL.max_wheel_speed * _MODEL.wheel_radius
"""m/s: both wheels at full speed (6.28 rad/s x 0.02 m = 0.1256 m/s); q stops there."""
MAX_TURN = 2.0 * MAX_SPEED / _MODEL.wheel_separation
"""rad/s: turning in place with both wheels at full speed (4.83 rad/s); q stops there."""
STOP_ACK_TIMEOUT = 2.0
"""Wall seconds to wait, on exit, for the subscribers to acknowledge the zero Twist."""

MOTIONS: dict[str, tuple[int, int]] = {
    'w': (1, 0), 'up': (1, 0), 's': (-1, 0), 'down': (-1, 0),
    'a': (0, 1), 'left': (0, 1), 'd': (0, -1), 'right': (0, -1),
}
STOP_KEYS = {' ', 'k', 'x'}
FASTER, SLOWER = 'q', 'z'
_ARROWS = {'A': 'up', 'B': 'down', 'C': 'right', 'D': 'left'}

PARAMETERS = (
    ParamSpec('speed', 0.1, 'forward speed (m/s) of w / up; more than the e-puck\'s 0.126 m/s is taken as 0.126',
              (0.0, 1.0)),
    ParamSpec('turn', 1.5, 'turning speed (rad/s) of a / left; more than the e-puck\'s 4.83 rad/s in place is taken '
                           'as 4.83', (0.0, 20.0)),
    ParamSpec('repeat_rate', 10.0, 'times a second the current command is re-sent; 0 = only on a key', (0.0, 1000.0)),
)
OPTIONS = '  --robot NAME  drive NAME/cmd_vel (a simulation of several robots); default: cmd_vel'
USAGE = Usage(
    program='teleop',
    summary='Drive a robot with the keyboard: w/up forward, s/down backward, a/left and d/right turn in place, '
            'space/k/x stop, q/z 10 % faster/slower; Ctrl-C or end of input quits '
            '(sending a stop). Publishes geometry_msgs/Twist on cmd_vel; reads a pipe as well as a terminal.',
    example='teleop --robot epuck3 --ros-args -p speed:=0.05',
    options=OPTIONS)

HELP_LINE = 'w/s forward/back, a/d turn, space stop, q/z faster/slower, Ctrl-C quit'


@dataclass
class Teleop:
    """The keyboard state machine without ROS: keys in, (linear, angular) out."""

    speed: float
    turn: float
    forward: int = 0
    rotation: int = 0

    def __post_init__(self) -> None:
        self.speed, self.turn = min(self.speed, MAX_SPEED), min(self.turn, MAX_TURN)

    @property
    def command(self) -> tuple[float, float]:
        """(m/s, rad/s); a motion of 0 is exactly 0.0, whatever the speeds."""
        return (self.forward * self.speed if self.forward else 0.0,
                self.rotation * self.turn if self.rotation else 0.0)

    def press(self, key: str) -> bool:
        """Apply one key; True if the command or the speeds changed."""
        if key in MOTIONS:
            self.forward, self.rotation = MOTIONS[key]
        elif key in STOP_KEYS:
            self.forward = self.rotation = 0
        elif key in (FASTER, SLOWER):
            factor = SPEED_STEP if key == FASTER else 1.0 / SPEED_STEP
            self.speed = min(self.speed * factor, MAX_SPEED)
            self.turn = min(self.turn * factor, MAX_TURN)
        else:
            return False
        return True

    def describe(self) -> str:
        linear, angular = self.command
        top_speed = ' (the e-puck\'s top speed)' if self.speed >= MAX_SPEED else ''
        top_turn = ' (its top turn)' if self.turn >= MAX_TURN else ''
        return (f'speed {self.speed:.3f} m/s{top_speed}, turn {self.turn:.2f} rad/s{top_turn} | '
                f'command: linear {linear:+.3f} m/s, angular {angular:+.2f} rad/s')


def read_keys(read_char: Callable[[], str]) -> Iterator[str]:
    """Keys from a character source ('' = end of input): letters lower-cased, arrow escape sequences as names."""
    while True:
        char = read_char()
        if char in ('', '\x03', '\x04'):  # end of input, Ctrl-C, Ctrl-D (the terminal is in cbreak mode)
            return
        if char == '\x1b' and read_char() == '[':
            arrow = _ARROWS.get(read_char())
            if arrow:
                yield arrow
        elif char not in '\r\n':
            yield char.lower()


@contextmanager
def single_characters(stream: object) -> Iterator[Callable[[], str]]:
    """A function reading one character of `stream`: a terminal is put in cbreak mode meanwhile (and restored)."""
    fd = stream.fileno()

    def read_char() -> str:
        return os.read(fd, 1).decode(errors='replace')
    if not os.isatty(fd):
        yield read_char
        return
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        yield read_char
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


class TeleopNode(Node):
    """Publishes the keyboard's Twist on `cmd_vel` (or `<robot>/cmd_vel`) and re-sends it at `repeat_rate`."""

    def __init__(self, robot: str) -> None:
        super().__init__('teleop')
        self._created = time.monotonic()
        values = declare_parameters(self, PARAMETERS)
        self.keys = Teleop(values['speed'], values['turn'])
        self._lock = threading.Lock()
        self.publisher = self.create_publisher(Twist, f'{robot}/cmd_vel' if robot else 'cmd_vel', 10)
        if values['repeat_rate'] > 0.0:
            self.create_timer(1.0 / values['repeat_rate'], self.publish)
        self.get_logger().info(f'driving {self.publisher.topic_name}: {HELP_LINE}')

    def press(self, key: str) -> None:
        with self._lock:
            changed = self.keys.press(key)
        if changed:
            self.publish()
            print(self.keys.describe(), flush=True)

    def publish(self) -> None:
        with self._lock:
            linear, angular = self.keys.command
        twist = Twist()
        twist.linear.x, twist.angular.z = linear, angular
        self.publisher.publish(twist)

    def stop(self) -> None:
        """Zero the command and wait until every subscriber has it (bounded), so the robot stops; a subscriber
        still being discovered or matched (teleop leaving at once, its input closed) is waited for first: any
        node may drive on cmd_vel, not only the package's."""
        with self._lock:
            self.keys.forward = self.keys.rotation = 0
        wait_until_matched(self, {self.publisher.topic_name: self.publisher}, self._created, STOP_ACK_TIMEOUT,
                           discovery_window=FOREIGN_DISCOVERY_WINDOW)
        self.publish()
        self.publisher.wait_for_all_acked(rclpy.duration.Duration(seconds=STOP_ACK_TIMEOUT))
        print('stopped', flush=True)


def _robot_name(text: str) -> str:
    if text and (not ROBOT_NAME.match(text) or '__' in text or len(text) > ROBOT_NAME_MAX):
        raise argparse.ArgumentTypeError(f'{text!r} is not a robot name (a ROS name: [A-Za-z_][A-Za-z0-9_]*, '
                                         f'at most {ROBOT_NAME_MAX} characters)')
    return text


def parse_options(args: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='teleop', add_help=False)
    parser.add_argument('--robot', default='', type=_robot_name, help='robot name: publishes on NAME/cmd_vel')
    return parser.parse_args(user_arguments(args))


def main(args: list[str] | None = None) -> None:
    argv = list(sys.argv if args is None else ['teleop', *args])
    ros_argv = prepare_arguments(argv, PARAMETERS, USAGE, own_options=True)
    options = parse_options(argv)
    # rclpy's own handlers would shut the context down at once, before the stop could be sent: Ctrl-C and
    # SIGTERM become KeyboardInterrupt here, and the `finally` below stops the robot, then shuts down.
    use_package_profile()
    rclpy.init(args=ros_argv, signal_handler_options=SignalHandlerOptions.NO)
    interrupt_on_signals()
    node, spinner = None, None
    executor = SingleThreadedExecutor()
    try:
        node = TeleopNode(options.robot)
        executor.add_node(node)
        # teleop_twist_keyboard's pattern: spin in a thread while the main thread blocks on the keyboard.
        spinner = threading.Thread(target=executor.spin, name='teleop_spin', daemon=True)
        spinner.start()
        print(node.keys.describe(), flush=True)
        if sys.stdin is None or sys.stdin.closed:
            print('teleop: no input (standard input is closed): stopping the robot and leaving', flush=True)
            return
        with single_characters(sys.stdin) as read_char:
            for key in read_keys(read_char):
                node.press(key)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            try:
                node.stop()
            except KeyboardInterrupt:   # Ctrl-C while stopping (after the input ended): leave without the wait
                node.publish()   # stop() zeroed the command first
                print('teleop: interrupted while stopping: the stop was sent, not waited for', flush=True)
        executor.shutdown()
        if spinner is not None:
            spinner.join()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
