"""The QoS profiles this package's topics share, defined once so a publisher and its readers always match."""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, QoSProfile

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Published once, kept for late readers (ROS 1's latched topics): the world, its markers, contact counts."""
