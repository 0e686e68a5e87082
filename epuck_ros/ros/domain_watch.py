"""One simulator per ROS domain: the sim looks for another before its first step, and keeps an eye out after.

Two simulators on a domain would both publish `/clock` and mix up simulated time. Before its first step the sim
looks at the graph for another `/clock` publisher (or a node with its name) for a discovery window; simulators
also announce when they started (`announcements`), so of two that meet the later refuses and the earlier goes on.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable

from rclpy.node import Node
from std_msgs.msg import String

from epuck_ros.ros.announcements import SIMULATORS_TOPIC, announcement, parse_announcement
from epuck_ros.ros.qos import ANNOUNCEMENT_QOS
from epuck_ros.ros.robot_ports import quiet_publisher

DISCOVERY_WINDOW = 1.0
"""The default of `discovery_window`: wall seconds from the creation of the sim's node (its DDS participant is up)
during which it looks for another simulator (another `/clock` publisher, or a node with its name) before it steps
or publishes anything. Participants announce themselves every 0.5 s (fastdds_profiles.xml), so one already running
is discovered within about that. A simulator discovered later still is caught by the announcements on
SIMULATORS_TOPIC: the later of two refuses then, the earlier goes on. The window is most of the time to first motion
(benchmarks/bench_startup.py), so it is no longer than it must be."""
ANNOUNCEMENT_WAIT = 3.0
"""Wall seconds a `/clock` publisher seen in the graph during the discovery window may go unexplained by a newer
simulator's announcement before this simulator refuses (a bag player, or an older simulator, never announces later)."""
WATCH_PERIOD = 2.0
"""Wall seconds between two looks for another `/clock` publisher once running."""
DISCOVERY_POLL = 0.05
"""Wall seconds between two looks at the graph during the discovery window."""


class DomainWatch:
    """Whether this simulator may run: `alone(keep_looking)` before the first step (the loop thread), then a timer
    and the announcements (the executor thread). `refusal` says why not, once it will not run."""

    def __init__(self, node: Node, created: float, started: float, discovery_window: float) -> None:
        """`created`: monotonic time the node was made (the window counts from it); `started`: that of the process
        (this simulator's place among others: who came first)."""
        self._node = node
        self._window_end = created + discovery_window
        self.refusal = ''
        """Why this simulator will not run (another one is there); set once."""
        self._warned_newcomer = False
        self._newer_simulator_seen = False
        """A simulator that started after this one announced itself: it refuses, this one goes on."""
        self._watching = False
        started_ns = time.time_ns() - round((time.monotonic() - started) * 1e9)
        self._identity = announcement(started_ns, os.getpid())
        quiet_publisher(node, String, SIMULATORS_TOPIC, ANNOUNCEMENT_QOS).publish(String(data=self._identity.text()))
        node.create_subscription(String, SIMULATORS_TOPIC, self._on_simulator, ANNOUNCEMENT_QOS)
        node.create_timer(WATCH_PERIOD, self._watch_for_newcomers)

    def alone(self, keep_looking: Callable[[], bool]) -> bool:
        """Before the first step: look for another simulator until the discovery window ends; refuse if there is.

        Another `/clock` publisher in the graph may be a simulator that started after this one (under load this
        one's window can outlast a newcomer's start-up): that one refuses by the announcements. So the graph alone
        refuses only if no newer simulator's announcement explains it within ANNOUNCEMENT_WAIT. `keep_looking()`
        False ends the look (the node is stopping): False if that is because it refused (the refusal, set by the
        announcements on the executor thread, stops the node; a second sim said "sim ready", then refused)."""
        seen_at = None
        while keep_looking():
            if self.refusal:
                return False
            now = time.monotonic()
            found = '' if self._newer_simulator_seen else self._another_simulator()
            if found:
                seen_at = now if seen_at is None else seen_at
                if now - seen_at >= ANNOUNCEMENT_WAIT:
                    self.refusal = self._refusal(found)
                    return False
            elif now >= self._window_end:
                self._watching = True
                return True
            time.sleep(DISCOVERY_POLL)
        return not self.refusal

    def _another_simulator(self) -> str:
        """What shows another simulator (another `/clock` publisher: a sim, a bag being played; or a node with this
        one's name), or ''."""
        node = self._node
        clocks = node.get_publishers_info_by_topic('/clock')
        if len(clocks) > 1:  # ours is one
            who = ', '.join(sorted({f'{c.node_namespace.rstrip("/")}/{c.node_name}' for c in clocks
                                    if not c.node_name.startswith('_NODE_NAME_UNKNOWN')})) or 'another node'
            return f'/clock is published by {who}'
        if node.get_node_names_and_namespaces().count((node.get_name(), node.get_namespace())) > 1:
            return f'a node named {node.get_fully_qualified_name()} exists'
        return ''

    def _on_simulator(self, msg: String) -> None:
        """Another simulator's announcement: the one that started later refuses to run."""
        other = parse_announcement(msg.data)
        if other is None or other == self._identity or self.refusal:
            return
        who = f'pid {other.pid} on {other.host}'
        if other < self._identity:
            self.refusal = self._refusal(
                f'the simulator {who} started {(self._identity.started_ns - other.started_ns) * 1e-9:.1f} s earlier')
        else:
            self._newer_simulator_seen = True
            if not self._warned_newcomer:
                self._warned_newcomer = True
                self._node.get_logger().warning(f'another simulator appeared ({who}): it refuses to run')

    def _watch_for_newcomers(self) -> None:
        """Once running: a clock source that appears later is worth one warning."""
        if not self._watching or self._warned_newcomer:
            return
        found = self._another_simulator()
        if found:
            self._warned_newcomer = True
            self._node.get_logger().warning(f'another clock source appeared ({found}): a simulator refuses to run, '
                                            'anything else mixes up simulated time')

    @staticmethod
    def _refusal(found: str) -> str:
        return (f'another simulator runs on ROS domain {os.environ.get("ROS_DOMAIN_ID", "0")}: {found}; '
                'stop it or use another ROS_DOMAIN_ID')
