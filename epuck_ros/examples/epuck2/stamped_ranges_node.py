"""The README's node on the e-puck's own interface: it reads `ps0`..`ps7` (sensor_msgs/Range) and answers each step on
`cmd_vel` with a geometry_msgs/TwistStamped stamped with the step it read, so a lockstep run is reproducible.

The same decision as `examples/stamped_node.py` (which reads our `ir_raw` and answers on `wheel_cmd`), written only
with the topics and types the real e-puck2 and Webots' ROS 2 e-puck share: a TwistStamped on `cmd_vel` is what
Webots' e-puck takes on Jazzy (diff_drive_controller); the simulator takes it with `-p cmd_vel_stamped:=true`.
No import of epuck_ros. Before its first answer it declares itself in lockstep on `/lockstep_declarations` (a latched
std_msgs/String the simulator reads; elsewhere nobody reads it), so the simulator waits for it however long that
first answer takes.

Run it:  bringup --controller epuck_ros/examples/epuck2/stamped_ranges_node.py -p cmd_vel_stamped:=true --duration 5
"""
from functools import partial

import rclpy
from geometry_msgs.msg import TwistStamped
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Range
from std_msgs.msg import String

SENSORS = [f'ps{index}' for index in range(8)]
SPEED = 0.06           # m/s with nothing ahead
TURN = 2.0             # rad/s on the spot
NEAR = 0.0665          # m: a range below this is an obstacle (the course's raw threshold 80)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
ANSWERS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""Reliable, and kept for a recorder that matched late or lags behind (rclpy's default depth 10 lost answers)."""


class StampedRangesNode(Node):
    """Answers each step, once all eight ranges of that step are in, with a TwistStamped naming it."""

    def __init__(self) -> None:
        super().__init__('stamped_ranges_node')
        self.ranges: dict[tuple[int, int], dict[str, float]] = {}
        for name in SENSORS:
            self.create_subscription(Range, name, partial(self.on_range, name),
                                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        # Last, the declaration and then the publisher: a lockstep simulator takes a command publisher for a
        # controller ready to answer (its readers made first, the first step is not sent before they are matched).
        command_topic = self.resolve_topic_name('cmd_vel')
        self.declaration = self.create_publisher(String, '/lockstep_declarations', LATCHED)
        self.declaration.publish(String(data=f'lockstep {command_topic}'))
        self.publisher = self.create_publisher(TwistStamped, 'cmd_vel', ANSWERS)

    def on_range(self, name: str, msg: Range) -> None:
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        step = self.ranges.setdefault(stamp, {})
        step[name] = msg.range
        if len(step) < len(SENSORS):
            return
        del self.ranges[stamp]
        for older in [other for other in self.ranges if other < stamp]:   # a step whose ranges never all came
            del self.ranges[older]
        command = TwistStamped()
        command.header.stamp = msg.header.stamp                  # the step it answers
        command.twist.linear.x, command.twist.angular.z = self.decide(step)
        self.publisher.publish(command)

    @staticmethod
    def decide(ranges: dict[str, float]) -> tuple[float, float]:
        """Forward, or turning on the spot away from the nearer side when ps0/ps1 (right front) or ps6/ps7 (left
        front) see something close."""
        right, left = min(ranges['ps0'], ranges['ps1']), min(ranges['ps6'], ranges['ps7'])
        if min(left, right) >= NEAR:
            return SPEED, 0.0
        return (0.0, -TURN) if left < right else (0.0, TURN)


def main() -> None:
    rclpy.init()
    node = StampedRangesNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:   # rclpy 7.1 fails a wait or take that Ctrl-C's shutdown cuts short (one Ctrl-C in eight)
        if rclpy.ok():   # an error of the running node: shown
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
