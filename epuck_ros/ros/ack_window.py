"""Keep the simulator at most a window of steps ahead of its reliable subscribers (a recorder): none loses a step.

A reliable KEEP_LAST publisher overwrites the oldest sample of its history even when a reader has not
acknowledged it yet: a recorder that falls behind at `real_time_factor` 0 silently loses steps. So every `window`
steps (below the publishers' history depth) the simulation loop waits until every reliable reader has acknowledged
everything published (`Publisher.wait_for_all_acked`); no sample a reliable reader has not acknowledged is ever
overwritten. Best-effort readers (a viewer) never acknowledge and are never waited for. A reader that takes its
samples KEEP_ALL with bounded resources (the recorder) acknowledges only what it has room for, so the simulator
runs at the speed of its slowest recorder — the right trade for a recording — while readers with a KEEP_LAST
history acknowledge on arrival and cost one round trip per window.

rclpy's `wait_for_all_acked` holds the GIL while it waits (every other thread of the process stands still for as
long as the wait), so it is only ever called with a zero timeout, and the waiting is done in short sleeps between
calls.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from rclpy.duration import Duration
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

HISTORY_BUDGET = 3000
"""Steps of history the simulator's per-step publishers keep, shared by its robots (`history_steps`). A longer
history lets the simulator run further ahead of its reliable readers between two looks at their
acknowledgements. In lockstep (published synchronously) a reader acknowledges only at the writer's next
heartbeat (its period: fastdds_profiles.xml), so each full window costs a wait of part of a heartbeat period,
and a lone robot's lockstep run steps fast enough that short windows made these waits a large share of its time:
fewer, longer windows make it faster (benchmarks/bench_lockstep.py). Memory: a volatile writer drops a sample as
soon as every reader acknowledged it, so a history holds only what a reader lags behind, at most a window (Fast
DDS's DataWriterImpl, onWriterChangeReceivedByAll)."""
MIN_HISTORY_STEPS = 300
"""Steps of history each robot's publishers keep at least (ten robots or more)."""
GIVE_UP = 10.0
"""Wall seconds a reader may go without acknowledging before the simulator stops waiting for it (a hung or
killed process that DDS has not yet noticed); the node is told so it can warn. The publisher is then not
waited for again until its number of readers changes."""
POLL = 0.0005
"""Wall seconds between two looks at the acknowledgements while waiting."""
READERS_WAIT = 10.0
"""Wall seconds the first step waits at most for the readers the graph shows to be matched (`await_readers`): a
reader whose QoS cannot match is in the graph for ever."""
READERS_POLL = 0.05
"""Wall seconds between two looks at the matched readers before the first step."""
_NOW = Duration(nanoseconds=0)


def history_steps(robots: int) -> int:
    """Steps of history each per-step publisher of a simulator of `robots` robots keeps: HISTORY_BUDGET shared,
    at least MIN_HISTORY_STEPS (so the memory a lagging reader can hold does not grow with the robots)."""
    return max(MIN_HISTORY_STEPS, HISTORY_BUDGET // max(1, robots))


def command_qos(robots: int) -> QoSProfile:
    """What a controller driving `robots` robots from one process publishes each `wheel_cmd` with.

    Its history is the simulator's (`history_steps`) for that many robots, which the simulator has at least: a
    recorder may read it as far behind as it reads the simulator (a shorter history lost commands at
    real_time_factor 0). Transient local, so that a recorder whose reader the controller's writer matched only after
    its first answers (DDS discovery between two other processes, under load) still gets them: a loaded
    `bringup --record` bag lacked one robot's first 88 commands. What is kept is bounded by the history per robot
    (its memory: benchmarks/bench_command_history.py)."""
    return QoSProfile(depth=history_steps(robots), reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def window_steps(history: int) -> int:
    """Steps the simulator may run ahead of what its reliable readers acknowledged: below the history, with room
    for the steps published while the last acknowledgements are on their way."""
    return history * 5 // 6


SHORT_WINDOW = window_steps(MIN_HISTORY_STEPS)
"""The window while a reader keeps all (see `AckWindow`): the one every simulator had before HISTORY_BUDGET."""


class AckWindow:
    """`published(step)` after each step: returns at once, or, every window of steps, once the readers caught up.

    The window is `window` steps, or SHORT_WINDOW while a topic has a reader that keeps all its samples (a
    recorder: `keeps_all(topic)`), worked out again at each look at the acknowledgements, the first one at once.
    Such a reader acknowledges only what it has room for (Fast DDS's default: 5,000 samples), and one refused
    sample holds back every later one: 2,500 steps of `proximity` are 20,000 samples, 250 steps 2,000."""

    def __init__(self, publishers: Callable[[], Sequence[Publisher]], window: int,
                 on_stall: Callable[[str], None], keeps_all: Callable[[str], bool]) -> None:
        self._publishers = publishers
        self._longest = window
        self._keeps_all = keeps_all
        self._window = 0
        """The window now (0: not worked out yet)."""
        self._on_stall = on_stall
        self._acked = 0
        """The last step known to be acknowledged by every reliable reader (or not waited for)."""
        self._running = True
        self._given_up: dict[Publisher, int] = {}

    def published(self, step: int) -> None:
        """Step `step` is out. Every quarter window, note whether the readers have caught up (only when a heartbeat
        was answered since the last publish: asynchronous sends carry heartbeats); a full window ahead, wait
        until they have."""
        if not self.due(step):
            return
        behind = step - self._acked
        pending = []
        self._window = self._longest
        for publisher in self._publishers():
            readers = publisher.get_subscription_count()
            if readers and self._window > SHORT_WINDOW and self._keeps_all(publisher.topic_name):
                self._window = SHORT_WINDOW
            if readers and self._given_up.get(publisher) != readers:
                self._given_up.pop(publisher, None)
                pending.append((publisher, readers))
        pending = [(publisher, readers) for publisher, readers in pending if not publisher.wait_for_all_acked(_NOW)]
        if pending and behind < self._window:
            return
        deadline = time.monotonic() + GIVE_UP
        while pending and self._running:
            pending = [(publisher, readers) for publisher, readers in pending
                       if not publisher.wait_for_all_acked(_NOW)]
            if pending and time.monotonic() > deadline:
                for publisher, readers in pending:
                    self._given_up[publisher] = readers  # until its readers change
                    self._on_stall(publisher.topic_name)
                break
            if pending:
                time.sleep(POLL)
        self._acked = step

    def await_readers(self, graph_readers: Callable[[str], int], keep_waiting: Callable[[], bool]) -> None:
        """Before the first step: until every publisher has matched as many readers as the graph shows on its topic
        (`graph_readers(topic)`), so each reader the graph shows gets the first step (a recorder started with the
        simulator missed it when its subscription was in the graph, but not yet matched by the simulator). At most
        READERS_WAIT, and only while `keep_waiting()`."""
        deadline = time.monotonic() + READERS_WAIT
        publishers = list(self._publishers())
        while publishers and self._running and keep_waiting() and time.monotonic() < deadline:
            publishers = [publisher for publisher in publishers
                          if publisher.get_subscription_count() < graph_readers(publisher.topic_name)]
            if publishers:
                time.sleep(READERS_POLL)

    def due(self, step: int) -> bool:
        """Whether `published(step)` would look at the acknowledgements (and perhaps wait for them)."""
        behind = step - self._acked
        return behind >= self._window or (behind >= self._window // 4 and not step % (self._window // 4))

    def restart(self, step: int) -> None:
        """Nothing before `step` needs acknowledging any more (after a pause, say)."""
        self._acked = step

    def close(self) -> None:
        """Stop waiting (the node is shutting down)."""
        self._running = False
