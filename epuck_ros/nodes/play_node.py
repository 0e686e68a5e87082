"""`bag play`: publishes a recorded bag on its topics, with /clock, as ``ros2 bag play --clock`` does.

Messages go out as their recorded CDR bytes (rclpy publishes bytes raw), each when the playback clock
reaches its log time (`epuck_ros.bag.play.PlaybackClock`), with the QoS its publishers offered (latched
topics transient local). /clock is published from the same clock, `--clock` times a wall second, its stamps
on a grid of the bag's time (`--rate` / `--clock` apart, so a recording of the playback finds no gap in them), never
ahead of the next message; the bag's own /clock is not replayed. The node is `bag_player`; pause and resume
with its std_srvs/Trigger services ``~/pause``, ``~/resume``, ``~/toggle_paused``, or Enter on a terminal.
"""
from __future__ import annotations

import argparse
import sys
import threading
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

from epuck_ros.bag.play import CLOCK_TOPIC, PlaybackClock, replay_profile
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.conversions import stamp_from_nanoseconds
from epuck_ros.exit_codes import ignore_ctrl_c_at_exit
from epuck_ros.ros.dds_profile import use_package_profile
from epuck_ros.ros.matching import FOREIGN_DISCOVERY_WINDOW, wait_until_matched
from epuck_ros.ros.qos import replayed
from epuck_ros.ros.spinning import interrupt_on_signals
from epuck_ros.nodes.record_node import message_class

MATCH_TIMEOUT = 10.0
"""s to wait at most, before the first message, for the subscribers in the graph to match each publisher."""
SETTLE = 0.3
"""s the subscribers of the played topics must stay the same, all matched: a recorder of every topic subscribes
only once it has seen our publishers (it looks every 0.2 s)."""
ACK_TIMEOUT = 5.0
"""s to wait at the end for reliable subscribers to acknowledge everything (exiting earlier would lose it)."""
PAUSED_POLL = 0.1
"""s between looks at the context while nothing is due (a shutdown by SIGTERM sets no event)."""


class Player(Node):
    """Publishers for the bag's topics, /clock, and the pause/resume services; `play` runs the playback."""

    def __init__(self, bag: Bag, topics: list[str] | None, rate: float, clock_hz: float, paused: bool,
                 wait: float = FOREIGN_DISCOVERY_WINDOW) -> None:
        """`wait`: wall seconds from now during which subscribers already running are looked for (`--wait`)."""
        super().__init__('bag_player', enable_rosout=False)  # its log lines must not mix with a replayed /rosout
        self._created = time.monotonic()
        self._wait = wait
        self._bag = bag
        self._outputs = {}
        wanted = {'/' + topic.lstrip('/') for topic in topics} if topics else None
        for name, topic in sorted(bag.topics.items()):
            if name == CLOCK_TOPIC or not topic.message_count or (wanted is not None and name not in wanted):
                continue
            try:
                msg_class = message_class(topic.type_name)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f'{name}: type {topic.type_name} is not installed: not played')
                continue
            profile = replay_profile(topic.offered_qos_profiles)
            self._outputs[name] = self.create_publisher(msg_class, name, replayed(profile))
        if wanted is not None and wanted - set(bag.topics):
            missing = ', '.join(sorted(wanted - set(bag.topics)))
            raise BagError(f'{bag.path}: no topic {missing} (topics: {", ".join(sorted(bag.topics))})')
        if not self._outputs:
            raise BagError(f'{bag.path}: nothing to play (no message on a topic whose type is installed)')
        self._clock_publisher = self.create_publisher(Clock, CLOCK_TOPIC, 10)
        self._start_ns = min(bag.topics[name].first_ns for name in self._outputs)
        self._clock_period = 1.0 / clock_hz
        self._tick_ns = max(1, round(rate * 1e9 / clock_hz))
        """Bag time between two /clock ticks: their stamps are on this grid, so a recorder of the playback finds no
        gap in them (ticks at wall instants had irregular stamps, reported as lost /clock messages)."""
        self._next_tick_ns = self._start_ns
        self._last_tick_ns = self._start_ns
        self._next_repeat = time.monotonic()
        """While paused: when the last tick is published again (a node on sim time still gets time)."""
        self.clock = PlaybackClock(self._start_ns, rate, time.monotonic(), paused)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self.create_service(Trigger, '~/pause', lambda _, response: self._set_paused(True, response))
        self.create_service(Trigger, '~/resume', lambda _, response: self._set_paused(False, response))
        self.create_service(Trigger, '~/toggle_paused',
                            lambda _, response: self._set_paused(not self.clock.paused, response))

    def _set_paused(self, paused: bool, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            was = self.clock.paused
            (self.clock.pause if paused else self.clock.resume)(time.monotonic())
        self._wake.set()
        response.success = True
        response.message = f'{"paused" if paused else "playing"}{" already" if was == paused else ""}'
        self.get_logger().info(response.message)
        return response

    def toggle(self) -> None:
        self._set_paused(not self.clock.paused, Trigger.Response())

    def wait_for_subscribers(self, timeout: float = MATCH_TIMEOUT) -> None:
        """Until every running subscriber of a played topic is matched and none came for `SETTLE` s, or `timeout`
        (then a warning naming the unmatched topics); at least the `wait` given from the start (by default
        FOREIGN_DISCOVERY_WINDOW: the subscribers are often a user's nodes, not the package's). Said before and
        after: a silent wait of seconds looked like a slow player. `wait` 0: no wait at all."""
        if self._wait <= 0:
            return
        began = time.monotonic()
        left = self._created + self._wait - began
        if left > 0:
            self.get_logger().info(f'waiting {left:.1f} s for subscribers already running to show in the graph '
                                   f'(--wait to change), then until each on a played topic is matched')
        unmatched = wait_until_matched(
            self, self._outputs, self._created, timeout, SETTLE,
            lambda topics: self.get_logger().info(f'waiting for the subscribers of {", ".join(topics)} to match '
                                                  f'(at most {timeout:.0f} s)'),
            discovery_window=self._wait)
        if unmatched:
            self.get_logger().warning(f'starting although {", ".join(unmatched)} still has subscribers not matched '
                                      f'after {timeout:.0f} s')
        matched = sum(publisher.get_subscription_count() for publisher in self._outputs.values())
        self.get_logger().info(f'waited {time.monotonic() - began:.2f} s: {matched} subscriptions matched on the '
                               f'played topics; playing')

    def play(self, loop: bool) -> int:
        """Publish the bag (again and again with `loop`); returns the number of messages published. Says how many
        in how long, from the first message (the wait before it said apart)."""
        published = 0
        if not self._wait_until_due(self._start_ns):  # paused until resumed (--start-paused)
            return published
        self.wait_for_subscribers()
        started = time.monotonic()
        with self._lock:
            self.clock.restart(self._start_ns, started)
            self._next_tick_ns = self._start_ns
        published = self._publish_all(loop)
        self.get_logger().info(f'played {published} messages in {time.monotonic() - started:.2f} s')
        return published

    def _publish_all(self, loop: bool) -> int:
        published = 0
        while self.context.ok():
            for topic, log_time, _, buffer, start, end in self._bag.iter_raw(self._outputs):
                if not self._wait_until_due(log_time):
                    return published
                self._outputs[topic].publish(bytes(buffer[start:end]))
                published += 1
            if not loop:
                break
            with self._lock:
                self.clock.restart(self._start_ns, time.monotonic())
                self._next_tick_ns = self._start_ns
        self.wait_for_acknowledgements()
        return published

    def wait_for_acknowledgements(self, timeout: float = ACK_TIMEOUT) -> None:
        """Until every reliable subscriber has acknowledged every message (as ros2 bag play --wait-for-all-acked)."""
        deadline = time.monotonic() + timeout
        for name, publisher in self._outputs.items():
            left = deadline - time.monotonic()
            if not publisher.wait_for_all_acked(Duration(seconds=max(left, 0.0))):
                self.get_logger().warning(f'{name}: not every subscriber acknowledged every message '
                                          f'within {timeout:.0f} s')

    def _wait_until_due(self, log_time: int) -> bool:
        """Publish the /clock ticks due before the message (their grid's, never past it; while paused the last one
        again every clock period) until the message is due; False when the node is shutting down."""
        while self.context.ok():
            now = time.monotonic()
            with self._lock:
                due = self.clock.due(log_time)
                reached = min(self.clock.bag_time(now), log_time)
                while self._next_tick_ns <= reached:
                    self._tick(self._next_tick_ns)
                    self._next_tick_ns += self._tick_ns
                if self.clock.paused and now >= self._next_repeat:
                    self._tick(self._last_tick_ns)
                    self._next_repeat = now + self._clock_period
                wake = self._next_repeat if self.clock.paused else self.clock.due(self._next_tick_ns)
            if now >= due:
                return True
            self._wake.wait(max(0.0, min(due, wake, now + PAUSED_POLL) - now))
            self._wake.clear()
        return False

    def _tick(self, bag_ns: int) -> None:
        self._last_tick_ns = bag_ns
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = stamp_from_nanoseconds(bag_ns)
        self._clock_publisher.publish(msg)


def _serve(executor: SingleThreadedExecutor) -> None:
    """The services' thread: spins until the executor or the context (Ctrl-C, SIGTERM) is shut down."""
    try:
        executor.spin()
    except ExternalShutdownException:
        pass


def _enter_toggles(player: Player) -> None:
    """Each line typed on the terminal pauses or resumes."""
    for _ in sys.stdin:
        player.toggle()


def play(args: argparse.Namespace) -> None:
    """`bag play` (see `epuck_ros.bag_cli`): plays until the end (or Ctrl-C / SIGTERM with --loop)."""
    ignore_ctrl_c_at_exit()
    with Bag(args.path) as bag:
        use_package_profile()
        rclpy.init(args=['bag', *args.ros_args], signal_handler_options=SignalHandlerOptions.NO)
        interrupt_on_signals()
        player, executor, services = None, None, None
        try:
            player = Player(bag, args.topics, args.rate, args.clock, args.start_paused, args.wait)
            executor = SingleThreadedExecutor()
            executor.add_node(player)
            services = threading.Thread(target=_serve, args=(executor,), name='services')
            services.start()
            if args.start_paused:
                how = 'press Enter or call' if sys.stdin.isatty() else 'call'
                player.get_logger().info(f'paused: {how} {player.get_fully_qualified_name()}/resume')
            if sys.stdin.isatty():
                threading.Thread(target=_enter_toggles, args=(player,), name='keys', daemon=True).start()
            player.play(args.loop)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:
            if player is None or player.context.ok():
                raise  # a publish failing because Ctrl-C shut the context down is part of stopping
        finally:
            if executor is not None:
                executor.shutdown(timeout_sec=1.0)
            if services is not None:
                services.join()
            if player is not None:
                player.destroy_node()
            rclpy.try_shutdown()
