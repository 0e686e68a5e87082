"""The QoS profiles this package's topics share, defined once so a publisher and its readers always match."""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from epuck_ros.nodes.ack_window import command_qos

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Published once, kept for late readers (ROS 1's latched topics): the world, its markers, contact counts."""

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
waits for a reader that keeps all (nodes/ack_window.py), however far behind it falls. A KEEP_LAST reader of any
depth is not waited for and skips steps under load (`bringup`'s summary: 0.376 m against the bag's 0.374 m)."""
