"""The simulator's `lockstep_status`: whether the run is reproducible (epuck_ros/integrity.py), latched, so a
reader that comes late (bringup's summary, the fixture, a recorder) gets the verdict."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.node import Node

from epuck_ros.integrity import STATUS_TOPIC, Integrity
from epuck_ros.nodes.qos import LATCHED
from epuck_ros.nodes.robot_ports import quiet_publisher


class IntegrityPort:
    """Publishes the run's verdict on `lockstep_status` when it changes (see epuck_ros/integrity.py)."""

    def __init__(self, node: Node, integrity: Integrity) -> None:
        self._publisher = quiet_publisher(node, DiagnosticStatus, STATUS_TOPIC, LATCHED)
        self.integrity = integrity
        self.publish(integrity)

    def publish(self, integrity: Integrity) -> None:
        self.integrity = integrity
        level, name, message, values = integrity.fields()
        self._publisher.publish(DiagnosticStatus(level=bytes([level]), name=name, message=message,
                                                 values=[KeyValue(key=key, value=value) for key, value in values]))
