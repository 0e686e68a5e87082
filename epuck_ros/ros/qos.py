"""The QoS profiles this package's topics share, each built here once and used by name, so a publisher and its
readers always match; and the one rule for a reader that matches whatever publishers a topic has (`matching`)."""
from __future__ import annotations

from collections.abc import Sequence

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from epuck_ros.bag.qos import QosProfile
from epuck_ros.ros.ack_window import command_qos

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Published once, kept for late readers (ROS 1's latched topics): the world, its markers, contact counts."""

ANNOUNCEMENT_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""The simulators' announcements (`announcements.SIMULATORS_TOPIC`): transient local, so a later reader gets every
simulator's announcement; depth for a few simulators per process."""

CONTROLLER_READS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
"""How a behaviour node reads its robot's step topics (`odom`, `ir_raw`, `proximity`, `/clock`)."""

SCRIPT_READS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
"""How a Webots script's link (`webots.link`) reads its robot's step and sense topics."""

SENSES_ON_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""A robot's `senses_on` (`sense_ports`) is latched with its last changes: a recorder that subscribes late still
learns when each began."""

DECLARATIONS_READ = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""How the simulator reads the controllers' declarations (`declaration`): every process's latched declaration,
however many come at once (a swarm's)."""


def declarations_kept(robots: int) -> QoSProfile:
    """How a process publishes its declarations (`declaration.Declarer`): reliable, latched, one kept per robot it
    drives."""
    return QoSProfile(depth=max(1, robots), reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


COMMAND_READER_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""How the simulator reads `swarm/command` (`swarm_ports`): transient local, so a controller's declaration, sent
before the simulator may have matched it, arrives once it does."""


def newest(depth: int) -> QoSProfile:
    """Best effort, the last `depth` samples: a reader the simulator never waits for, which sees the newest."""
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT)


NEWEST_ONLY = newest(1)
"""The newest sample of a topic, never waited for: the view's readings, the Foxglove bridge's `/clock` (as
foxglove_bridge reads it)."""


def step_stream(history: int) -> QoSProfile:
    """How the simulator publishes its per-step topics: reliable, volatile, the last `history` steps kept
    (`ack_window.history_steps`: the acknowledgement window runs within it)."""
    return QoSProfile(depth=history, reliability=ReliabilityPolicy.RELIABLE)


def deeper(qos: QoSProfile, factor: int) -> QoSProfile:
    """`qos` with `factor` times the history: a topic with several messages per step (`proximity`: one per sensor;
    `/tf`: one per robot)."""
    return QoSProfile(history=qos.history, depth=qos.depth * factor, reliability=qos.reliability,
                      durability=qos.durability)


def matching(offered: Sequence[QoSProfile], depth: int, keep_all: bool = False) -> QoSProfile:
    """A reader that matches every publisher in `offered` (as the graph reports them): reliable only if all of them
    are, transient local only if all of them are (none offered: best effort, volatile); KEEP_LAST `depth`, or, with
    `keep_all`, KEEP_ALL when reliable (the recorder: DDS then acknowledges a sample only once the reader has room
    for it, so the simulator waits for it; `ack_window`)."""
    reliable = bool(offered) and all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = bool(offered) and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all and reliable else HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def replayed(recorded: QosProfile) -> QoSProfile:
    """What `bag play` publishes a topic with, from the profile its publishers offered when recorded
    (`bag.play.replay_profile`): KEEP_LAST, the recorded depth, reliability and durability."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=recorded.depth,
        reliability=ReliabilityPolicy.RELIABLE if recorded.reliability == 'reliable' else ReliabilityPolicy.BEST_EFFORT,
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if recorded.durability == 'transient_local'
                    else DurabilityPolicy.VOLATILE))


LED_QOS = command_qos(1)
"""A controller's LEDs: latched (a view started later still draws them), with the history of a script's wheel_cmd
(`ack_window.command_qos(1)`): a script may set them every step, and a reliable writer replaces a sample a recorder
has not acknowledged yet once its history is full (a history of one lost LED messages in recordings; README, Bags)."""


def clock_kept(depth: int) -> QoSProfile:
    """`/clock` as the simulator offers it (a headless bag records it so): reliable, its last `depth` ticks kept
    for a reader matched late (CLOCK_KEPT)."""
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


CLOCK_KEPT = clock_kept(10)
"""How `bringup`'s monitor reads `/clock`, and the durability the simulator offers it with: its last ticks are kept
for a reader matched late (or matched anew). In a 500-robot run the simulator paused itself at the run's end while
the monitor had not got the last ticks (a swarm's discovery lags by tens of seconds), and bringup waited for ever;
a volatile reader (rclpy's clock, the controllers) gets only what comes after it matched, as before."""


EVERY_STEP = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
"""How a reader that needs every step's message reads a per-step topic (`bringup`'s ground truth): the simulator
waits for a reader that keeps all (ros/ack_window.py), however far behind it falls. A KEEP_LAST reader of any
depth is not waited for and skips steps under load (`bringup`'s summary then disagreed with the bag's)."""
