"""Drive straight ahead until odometry says DISTANCE metres, then stop: an odometry loop on /odom with a Twist on
/cmd_vel, written as nodes for the e-puck are (webots_ros2_epuck's drive_calibrator.py is one), so it runs unchanged
on the physical e-puck2 (epuck_ros2's driver) and in Webots' simulated e-puck.

Run beside the simulator (`sim`):  python3 odometry_drive.py --ros-args -p distance:=0.2
A Twist names no step, so the simulator does not wait for this node (it runs at its own rate, as on the robot).
"""
import math
import sys

import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

SPEED = 0.05   # m/s


class OdometryDrive(Node):
    def __init__(self):
        super().__init__('odometry_drive')
        self.distance = self.declare_parameter('distance', 0.2).value
        self.start = None
        self.done = False
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(Odometry, 'odom', self.on_odometry, 10)

    def on_odometry(self, msg):
        position = msg.pose.pose.position
        if self.start is None:
            self.start = (position.x, position.y)
        travelled = math.hypot(position.x - self.start[0], position.y - self.start[1])
        command = Twist()
        if travelled >= self.distance:
            self.done = True
            self.get_logger().info(f'travelled {travelled:.4f} m by odometry: stopping')
        else:
            command.linear.x = SPEED
        self.publisher.publish(command)


def main():
    rclpy.init(args=sys.argv)
    node = OdometryDrive()
    try:
        while rclpy.ok() and not node.done:
            rclpy.spin_once(node, timeout_sec=0.1)
        node.publisher.wait_for_all_acked(Duration(seconds=1.0))   # the stop delivered before the process ends
    except (KeyboardInterrupt, ExternalShutdownException):   # Ctrl-C, or the process told to stop
        pass
    except Exception:   # rclpy 7.1 fails a wait or take that Ctrl-C's shutdown cuts short (one Ctrl-C in eight)
        if rclpy.ok():   # an error of the running node: shown
            raise
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
