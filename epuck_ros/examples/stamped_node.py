"""A user's own rclpy controller that answers every step by name: the whole node the README's snippet is part of.

It reads `ir_raw` (the eight raw IR values of one step, as bytes) and answers that very step on `wheel_cmd` with
`[left, right]` rad/s whose layout names the step (`array_bytes(..., stamp)`): the simulator pairs the answer with
its step, so a lockstep run is reproducible. It drives forward and turns away from whatever its front sensors see.

Run it:  bringup --controller epuck_ros/examples/stamped_node.py --duration 5
or on its own beside `sim`:  python3 epuck_ros/examples/stamped_node.py --ros-args -p use_sim_time:=true

`wheel_cmd` is published with `command_qos(1)`: reliable, transient local, a history as long as the simulator's
for one robot, so a recorder that lags behind (or matched late) still gets every answer; rclpy's default (depth 10,
volatile) lost answers in a loaded recorded run. It stops on Ctrl-C (SIGINT, what `bringup` sends first) or
SIGTERM (rclpy then ends the spin with ExternalShutdownException) without a traceback, exit code 0.
"""
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray

from epuck_ros.ros.ack_window import command_qos
from epuck_ros.ros.serialized import array_bytes, array_values

CRUISE = 3.0
"""rad/s of each wheel with nothing ahead."""
NEAR = 80.0
"""A raw IR value above this is an obstacle closer than about 6.7 cm (the course's threshold)."""


class StampedNode(Node):
    """Answers each step's `ir_raw` with a `wheel_cmd` naming that step."""

    def __init__(self) -> None:
        super().__init__('stamped_node')
        self.create_subscription(Float64MultiArray, 'ir_raw', self.on_ir_raw,
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE), raw=True)
        # Last: a lockstep simulator (and bringup) takes a wheel_cmd publisher for a controller ready to answer; made
        # before the reader, the first step could go out before the reader was matched, and wait for a resend.
        self.publisher = self.create_publisher(Float64MultiArray, 'wheel_cmd', command_qos(1))

    def on_ir_raw(self, data: bytes) -> None:
        read = array_values(data)                        # None: bytes that are no Float64MultiArray
        if read is None or read[1] is None:              # not a step's values: nothing to answer
            return
        values, stamp = read                             # stamp: (sec, nanosec) of the step
        self.publisher.publish(array_bytes(self.decide(values), stamp))   # wheel_cmd naming that step

    @staticmethod
    def decide(values: tuple[float, ...]) -> tuple[float, float]:
        """Forward, or turning away from the nearer side when ps0/ps1 (right front) or ps6/ps7 (left front) see
        something close."""
        right, left = max(values[0], values[1]), max(values[6], values[7])
        if max(left, right) < NEAR:
            return CRUISE, CRUISE
        return (CRUISE, -CRUISE) if left > right else (-CRUISE, CRUISE)


def main() -> None:
    rclpy.init()
    node = StampedNode()
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
