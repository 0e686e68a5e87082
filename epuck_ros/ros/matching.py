"""Waiting, before a first message, until the subscribers the graph shows are matched (rclpy has no such call).

A publisher's first messages go to the readers it has matched; one whose reader is still being matched loses
them. A node just created knows the graph only after the discovery window (participants announce every 0.5 s in
the package's DDS profile), so the wait lasts at least that long from the node's creation.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping

from rclpy.node import Node
from rclpy.publisher import Publisher

DISCOVERY_WINDOW = 1.0
"""s from a node's creation before its view of the graph holds every participant of this package already running
(they announce every 0.5 s)."""
FOREIGN_DISCOVERY_WINDOW = 3.5
"""s from a node's creation before its view of the graph also holds every other participant already running (a
user's node, a test process) under Fast DDS's default profile, which announces every 3 s: such a participant
answers a new one at once, but when that answer is missed (often, on a loaded machine) it is seen only at its
next announcement."""


def wait_until_matched(node: Node, publishers: Mapping[str, Publisher], created: float, timeout: float,
                       settle: float = 0.0, say: Callable[[list[str]], None] | None = None,
                       say_after: float = 1.0, discovery_window: float = DISCOVERY_WINDOW) -> list[str]:
    """Wait until the graph has had `discovery_window` since `created` (time.monotonic()), every subscriber it shows
    on each topic of `publishers` is matched, and the counts stayed the same for `settle` s; at most `timeout` s
    once the discovery window is over. `say(topics)` is called once if the wait for a match lasts `say_after` s.
    Returns the topics still unmatched."""
    begin = time.monotonic()
    give_up = max(begin, created + discovery_window) + timeout
    seen, since, said = None, begin, False
    while node.context.ok():
        now = time.monotonic()
        counts = {name: (publisher.get_subscription_count(), node.count_subscribers(name))
                  for name, publisher in publishers.items()}
        waiting = sorted(name for name, (matched, in_graph) in counts.items() if matched < in_graph)
        if counts != seen:
            seen, since = counts, now
        if not waiting and now >= created + discovery_window and now - since >= settle:
            return []
        if now >= give_up:
            return waiting
        if waiting and say is not None and not said and now - begin >= say_after:
            say(waiting)
            said = True
        time.sleep(0.01)
    return []
