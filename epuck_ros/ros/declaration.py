"""A controller's declaration of which it is, before its first answer (`epuck_ros.lockstep.DECLARATION_TOPIC`):
made by the behaviours and the Webots link, read by the simulator, so that lockstep knows from the first step
whether to wait for a robot's controller as long as it takes, or not at all (never for a wall-clock time)."""
from __future__ import annotations

from collections.abc import Callable, Sequence

from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import String

from epuck_ros.lockstep import DECLARATION_TOPIC, Controller, declaration, read_declaration
from epuck_ros.ros.qos import DECLARATIONS_READ, declarations_kept


class Declarer:
    """A process's declarations: one latched publisher, keeping one declaration per robot it drives (`robots`), so
    that a simulator that comes later gets them all."""

    def __init__(self, node: Node, robots: int = 1) -> None:
        """`node`: any of the process's nodes, that lives as long as its controllers publish (the declarations go
        with its publisher)."""
        self.publisher = node.create_publisher(String, DECLARATION_TOPIC, declarations_kept(robots))

    def declare(self, controller: Controller, topics: Sequence[str]) -> None:
        """The publishers on `topics` (fully qualified) are `controller`: said before they are made."""
        self.publisher.publish(String(data=declaration(controller, topics)))

    def goodbye(self, topics: Sequence[str]) -> None:
        """The controllers on `topics` end on purpose: a lockstep simulator no longer waits for them once they have
        left (epuck_ros/lockstep.py). Their process waits until it is delivered (`delivered`) before it goes."""
        self.declare(Controller.OWN_RATE, topics)

    def delivered(self) -> bool:
        """Every reader acknowledged the declarations (not waiting)."""
        return self.publisher.wait_for_all_acked(Duration(seconds=0))


def read_declarations(node: Node, on_declared: Callable[[Controller, list[str]], None],
                      on_refused: Callable[[str], None]) -> None:
    """Hand each declaration on the domain to `on_declared`, and why one is refused to `on_refused`."""
    def take(message: String) -> None:
        try:
            on_declared(*read_declaration(message.data))
        except ValueError as error:
            on_refused(str(error))
    node.create_subscription(String, DECLARATION_TOPIC, take, DECLARATIONS_READ)
