"""Keep the simulator at most a window of steps ahead of its reliable subscribers (a recorder): none loses a step.

A reliable KEEP_LAST publisher overwrites the oldest sample of its history even when a reader has not
acknowledged it yet: a recorder that falls behind at `real_time_factor` 0 silently loses steps. Here a thread
waits, a batch of steps at a time, until every reliable reader has acknowledged everything published
(`Publisher.wait_for_all_acked`), and the simulation loop blocks only when it runs more than `window` steps
ahead of the last acknowledged batch. With `window` below the publishers' history depth, no sample a reliable
reader has not acknowledged is ever overwritten. Best-effort readers (a viewer) never acknowledge and are never
waited for. A reader that takes its samples (KEEP_ALL with bounded resources, as the recorder does) only
acknowledges what it has room for, so the simulator runs at the speed of its slowest recorder — the right
trade for a recording — while readers with a KEEP_LAST history acknowledge on arrival and cost almost nothing.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

from rclpy.duration import Duration
from rclpy.publisher import Publisher

GIVE_UP = 10.0
"""Wall seconds a reader may go without acknowledging before the simulator stops waiting for it (a hung or
killed process that DDS has not yet noticed); the node is told so it can warn. The publisher is then not
waited for again until its number of readers changes."""


class AckWindow:
    """`published(step)` after each step: returns at once, or waits while the readers are too far behind."""

    def __init__(self, publishers: Callable[[], Sequence[Publisher]], window: int,
                 on_stall: Callable[[str], None]) -> None:
        self._publishers = publishers
        self._window = window
        self._batch = max(1, window // 4)
        self._on_stall = on_stall
        self._published = 0
        self._acked = 0
        self._running = True
        self._given_up: dict[Publisher, int] = {}
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._acknowledge, name='ack_window', daemon=True)
        self._thread.start()

    def published(self, step: int) -> None:
        """Step `step` is out; block while more than `window` steps are not known to be acknowledged."""
        with self._changed:
            self._published = step
            if step - self._acked >= self._batch:
                self._changed.notify_all()
            while self._running and step - self._acked > self._window:
                self._changed.wait(0.1)

    def restart(self, step: int) -> None:
        """Nothing before `step` needs acknowledging any more (after a long pause, say)."""
        with self._changed:
            self._published = self._acked = step

    def close(self) -> None:
        with self._changed:
            self._running = False
            self._changed.notify_all()
        self._thread.join(timeout=2.0)

    def _acknowledge(self) -> None:
        while True:
            with self._changed:
                self._changed.wait_for(lambda: not self._running or self._published - self._acked >= self._batch)
                if not self._running:
                    return
                target = self._published
            self._wait_for_readers()
            with self._changed:
                self._acked = max(self._acked, target)
                self._changed.notify_all()

    def _wait_for_readers(self) -> None:
        deadline = time.monotonic() + GIVE_UP
        for publisher in self._publishers():
            readers = publisher.get_subscription_count()
            if not self._running:
                return
            if readers == 0 or self._given_up.get(publisher) == readers:
                continue
            self._given_up.pop(publisher, None)
            while self._running:
                left = deadline - time.monotonic()
                if publisher.wait_for_all_acked(Duration(seconds=max(0.0, min(1.0, left)))):
                    break
                if left <= 0.0:
                    self._given_up[publisher] = readers  # until its readers change
                    self._on_stall(publisher.topic_name)
                    break
