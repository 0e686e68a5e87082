"""The e-puck's own ROS 2 interface, as its two implementations define it: figures and conversions, no ROS.

Sources (read 2026-11-28): the physical e-puck2's driver, cyberbotics/epuck_ros2 `epuck_ros2_driver/src/driver.cpp`
("physical"), and Webots' simulated e-puck, cyberbotics/webots_ros2 `webots_ros2_epuck` (`epuck_webots.urdf`,
`epuck_node.py`) over `webots_ros2_driver`'s plugins ("Webots"). Where they differ the physical robot's form is
taken (code written here is to move to it) and the simulation's where it costs little; each choice is named at its
constant. ros/interface_ports.py publishes these topics on the simulator's node.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from epuck_ros.model import LIGHT_SENSOR_NAMES, SENSOR_NAMES

IR_TOPICS = SENSOR_NAMES
"""ps0..ps7: sensor_msgs/Range each, frame psN, radiation INFRARED (both sources)."""
IR_FIELD_OF_VIEW = 15.0 * math.pi / 180.0
"""rad: the physical driver's (Webots gives the DistanceSensor's aperture, 0.1 rad, which our ray models)."""
IR_MIN_RANGE, IR_MAX_RANGE = 0.009, 0.025
"""m: the physical driver's INFRARED_MIN_RANGE / INFRARED_MAX_RANGE (Webots: 0 and 0.0666 from its table). The
range itself is, in both sources, the raw value back through the sensor's lookup table, extrapolated and never inf
(`ir_sensor.distance_from_raw`, webots_ros2's interpolateLookupTable): so a free sensor reads about 0.07 m, beyond
max_range, as on the robot (our `proximity` topic says inf there instead, REP 117)."""
LIGHT_TOPICS = LIGHT_SENSOR_NAMES
"""ls0..ls7: sensor_msgs/Illuminance; `illuminance` is the raw value (the physical driver's: more light, lower
value; Webots gives the lookup table's inverse, an irradiance), variance 0; frame lsN (Webots'; the physical driver
sets none)."""
LED_TOPICS = tuple(f'led{i}' for i in range(10))
"""led0..led9, subscribed: std_msgs/Bool for led0, 2, 4, 6 and std_msgs/Int32 for the others (the physical driver's
types: its even LEDs are red on/off, its odd ones RGB as 0xRRGGBB; led8 and led9 exist only in Webots, Int32)."""
BOOL_LEDS = frozenset({0, 2, 4, 6})
SCAN_TOPIC, SCAN_FRAME = 'scan', 'laser_scanner'
SCAN_FRAME_HEIGHT = 0.033
"""m: base_link -> laser_scanner's z, Webots' (the IR ring's height, where the slots come from; the physical
driver: 0)."""
SCAN_ANGLE_MIN, SCAN_ANGLE_MAX, SCAN_ANGLE_INCREMENT = -150 * math.pi / 180, 150 * math.pi / 180, 15 * math.pi / 180
"""The 21 slots of the scan, in epuck_node.py's (and driver.cpp's) own arithmetic."""
SCAN_IR_LIMIT = 0.04
"""m: an IR range above it is out of the scan (epuck_node.py's INFRARED_MAX_RANGE; the physical driver uses 0.025)."""
SCAN_TOF_LIMIT = 1.0
"""m: a ToF range above it is out of the scan (both sources)."""
SENSOR_RING_RADIUS = 0.035
"""m: added to every range, so slots count from the robot's centre (both sources' SENSOR_DIST_FROM_CENTER)."""
SCAN_RANGE_MIN, SCAN_RANGE_MAX = SENSOR_RING_RADIUS + 0.009, SENSOR_RING_RADIUS + SCAN_TOF_LIMIT
OUT_OF_RANGE = 0.0
SCAN_SLOTS: tuple[int | None, ...] = (3, None, None, None, 2, None, None, 1, None, 0, -1,
                                      7, None, 6, None, None, 5, None, None, None, 4)
"""What each of the 21 slots (-150 deg to +150 deg by 15) carries: psN's index, -1 the ToF, None nothing."""
CAMERA_TOPICS = ('image_raw', 'camera_info')
"""The physical robot's camera names (epuck_ros2_camera): rgb8, as our camera/image_raw (Webots: camera/image_color,
bgra8, beside our camera/camera_info)."""


def float32(values: Sequence[float] | float) -> np.ndarray:
    """Values as a message's float32 field holds them and a reader gets them back (as Python floats)."""
    return np.asarray(values, dtype=np.float32).astype(np.float64)


def scan_ranges(ir_ranges: Sequence[float], tof_range: float) -> list[float]:
    """The scan's 21 ranges from the eight IR ranges and the ToF's as their Range messages carry them (float32),
    computed as epuck_node.py computes them (double arithmetic, stored as float32): equal to its scan to the bit."""
    ir = float32(ir_ranges)
    ir = np.where(ir > SCAN_IR_LIMIT, OUT_OF_RANGE, ir) + SENSOR_RING_RADIUS
    tof = float(float32(tof_range))
    tof = (OUT_OF_RANGE if tof > SCAN_TOF_LIMIT else tof) + SENSOR_RING_RADIUS
    values = [OUT_OF_RANGE if slot is None else tof if slot < 0 else ir[slot] for slot in SCAN_SLOTS]
    return float32(values).tolist()


def led_value(index: int, data: bool | int) -> int:
    """The value ledN takes from its topic's message, as Webots' LED.set takes it (our `leds` carries it): a Bool
    LED 1 or 0, an Int32 one its value (0xRRGGBB for an RGB LED of the e-puck2, any non-zero value lights the
    others)."""
    return int(bool(data)) if index in BOOL_LEDS else int(data)
