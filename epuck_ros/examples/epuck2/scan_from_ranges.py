"""A LaserScan built from the eight IR Range topics ps0..ps7 and the time-of-flight's `tof`, as webots_ros2_epuck's
epuck_node.py builds `/scan` (the 21 slots from -150 to +150 degrees by 15, an IR range beyond 0.04 m and a ToF
range beyond 1 m left out, 0.035 m added for the sensor ring's radius), published on `scan_rebuilt` once every
reading of one instant is in, with that instant's stamp. The simulator's own `scan` is built the same way: compare
the two (`ros2 topic echo scan_rebuilt` beside `ros2 topic echo scan`).

Run beside the simulator (`sim`):  python3 scan_from_ranges.py
"""
import sys
from functools import partial
from math import pi

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import LaserScan, Range

OUT_OF_RANGE = 0.0
INFRARED_MAX_RANGE = 0.04
INFRARED_MIN_RANGE = 0.009
TOF_MAX_RANGE = 1.0
SENSOR_DIST_FROM_CENTER = 0.035
SLOTS = [3, None, None, None, 2, None, None, 1, None, 0, 'tof', 7, None, 6, None, None, 5, None, None, None, 4]
"""What each slot from -150 degrees to +150 carries: psN's N, the ToF, or nothing."""


class ScanFromRanges(Node):
    def __init__(self):
        super().__init__('scan_from_ranges')
        self.readings = {}   # stamp -> {sensor: range}
        for index in range(8):
            self.create_subscription(Range, f'ps{index}', partial(self.on_range, index), 10)
        self.create_subscription(Range, 'tof', partial(self.on_range, 'tof'), 10)
        self.publisher = self.create_publisher(LaserScan, 'scan_rebuilt', 10)

    def on_range(self, sensor, msg):
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        readings = self.readings.setdefault(stamp, {})
        readings[sensor] = msg.range
        if len(readings) == 9:
            del self.readings[stamp]
            for older in [key for key in self.readings if key < stamp]:
                del self.readings[older]
            self.publish(msg.header.stamp, readings)

    def publish(self, stamp, readings):
        def slot(sensor):
            if sensor is None:
                return OUT_OF_RANGE
            limit = TOF_MAX_RANGE if sensor == 'tof' else INFRARED_MAX_RANGE
            distance = readings[sensor]
            return (OUT_OF_RANGE if distance > limit else distance) + SENSOR_DIST_FROM_CENTER

        msg = LaserScan()
        msg.header.frame_id = 'laser_scanner'
        msg.header.stamp = stamp
        msg.angle_min = - 150 * pi / 180
        msg.angle_max = 150 * pi / 180
        msg.angle_increment = 15 * pi / 180
        msg.range_min = SENSOR_DIST_FROM_CENTER + INFRARED_MIN_RANGE
        msg.range_max = SENSOR_DIST_FROM_CENTER + TOF_MAX_RANGE
        msg.ranges = [slot(sensor) for sensor in SLOTS]
        self.publisher.publish(msg)


def main():
    rclpy.init(args=sys.argv)
    node = ScanFromRanges()
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
