"""Which controllers' answer topics a recorder has heard from: how `bringup` knows a recorded run's answers will reach
the bag before it resumes the run.

Why: `bringup` sees the recorder's readers in its own graph, but whether a controller's writer has matched such a
reader is known only inside the controller. On a loaded machine a controller learnt of the recorder's readers more
than 0.8 s after `bringup` did; a 2 s run at `real_time_factor` 0 was over by then, and its bag held no answer.
A message the recorder receives from a writer proves that writer matched it. A controller's latched declaration
proves more: DDS sends a participant's reader announcements in the order the readers were made, reliably, so a
declaration received on a reader made after the reader of an answer topic proves the declaring process knows that
reader too. The recorder (`Recorder`) says here, latched, which answer topics it has heard of so; `bringup` waits
until they include every controller's it heard declared itself (`RunMonitor.recorder_heard`).

The topic is hidden (its name starts with an underscore): no recorder records it, no bridge forwards it.
"""
from __future__ import annotations

from collections.abc import Iterable

from rclpy.node import Node
from rclpy.publisher import Publisher
from std_msgs.msg import String

from epuck_ros.ros.declaration import read_declarations
from epuck_ros.ros.qos import LATCHED

HEARD_TOPIC = '/_recorder/heard'
"""std_msgs/String, latched: the fully qualified answer topics heard from, one per line."""
MAX_HEARD = 4_000_000
"""Characters read at most (20,000 robots' command topics): anyone on the domain can publish here."""


def heard_text(topics: Iterable[str]) -> str:
    return '\n'.join(sorted(topics))


def read_heard(text: str) -> frozenset[str]:
    """The topics of a message on HEARD_TOPIC; none from one too long, and only fully qualified names."""
    if len(text) > MAX_HEARD:
        return frozenset()
    return frozenset(line for line in text.split('\n') if line.startswith('/'))


class HeardPublisher:
    """The recorder's side: made with its first topic heard (a recorder that hears none adds nothing to the graph)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._publisher: Publisher | None = None
        self.topics: set[str] = set()

    def add(self, topics: Iterable[str]) -> None:
        new = set(topics) - self.topics
        if not new:
            return
        self.topics |= new
        if self._publisher is None:
            self._publisher = self._node.create_publisher(String, HEARD_TOPIC, LATCHED)
        self._publisher.publish(String(data=heard_text(self.topics)))


class HeardReader:
    """`bringup`'s side: the topics the recorder last said it heard from (`topics`), and the command topics the
    controllers declared, as this node heard them (`declared`)."""

    def __init__(self, node: Node) -> None:
        self.topics: frozenset[str] = frozenset()
        self.declared: set[str] = set()
        node.create_subscription(String, HEARD_TOPIC, self._on_heard, LATCHED)
        read_declarations(node, lambda _, topics: self.declared.update(topics), lambda why: None)   # the sim says why

    def _on_heard(self, message: String) -> None:
        self.topics = read_heard(message.data)
