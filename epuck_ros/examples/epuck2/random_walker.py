"""A random walker that avoids walls: straight ahead while the time-of-flight sensor (`tof`) and the two front IR
sensors (`ps0`, `ps7`) see nothing close, else a turn on the spot, away from the nearer side, for a random number of
readings. Topics and types are the e-puck's own (Range in, a Twist on `cmd_vel` out), so it runs unchanged on the
physical e-puck2 and in Webots' simulated e-puck.

Run beside the simulator (`sim`):  python3 random_walker.py --ros-args -p seed:=1
"""
import random
import sys
from functools import partial

import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import Range

SPEED = 0.08          # m/s straight ahead
TURN = 2.0            # rad/s on the spot
TOF_CLOSE = 0.12      # m: something ahead
IR_CLOSE = 0.06       # m: something at a front corner (a free IR sensor reads about 0.07)


class RandomWalker(Node):
    def __init__(self):
        super().__init__('random_walker')
        self.random = random.Random(self.declare_parameter('seed', 0).value)
        self.ranges = {'tof': float('inf'), 'ps0': float('inf'), 'ps7': float('inf')}
        self.turning = 0      # readings left to turn
        self.direction = 1.0
        for name in self.ranges:
            self.create_subscription(Range, name, partial(self.on_range, name), 10)
        self.publisher = self.create_publisher(Twist, 'cmd_vel', 10)

    def on_range(self, name, msg):
        self.ranges[name] = msg.range
        if name != 'tof':
            return
        command = Twist()
        blocked = self.ranges['tof'] < TOF_CLOSE or min(self.ranges['ps0'], self.ranges['ps7']) < IR_CLOSE
        if blocked and not self.turning:
            self.direction = 1.0 if self.ranges['ps0'] < self.ranges['ps7'] else -1.0   # ps0 is front right
            self.turning = self.random.randint(10, 40)
        if self.turning:
            self.turning -= 1
            command.angular.z = self.direction * TURN
        else:
            command.linear.x = SPEED
        self.publisher.publish(command)


def main():
    rclpy.init(args=sys.argv)
    node = RandomWalker()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):   # Ctrl-C, or the process told to stop
        pass
    except Exception:   # rclpy 7.1 fails a wait or take that Ctrl-C's shutdown cuts short (one Ctrl-C in eight)
        if rclpy.ok():   # an error of the running node: shown
            raise
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
