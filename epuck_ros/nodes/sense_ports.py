"""One robot's sense topics on the simulator node: camera/image_raw and camera/camera_info, ground_raw, light_raw,
imu (design.md, "Senses"); each sense is computed only while it is wanted.

Wanted means a subscriber on its topic (so an echo, RViz or a recorder just works), or the `senses` parameter.
The node looks at the subscriber counts every SENSE_POLL wall seconds (`update_wants`), not every step: a swarm's
thousands of topics would cost more than its steps. A sense newly wanted is read at once from the current state,
so the next step's messages carry it. Messages are serialised once and patched each step (`serialized`), the
image's pixels copied into the tail of its CDR bytes.
"""
from __future__ import annotations

from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CameraInfo, Image, Imu
from std_msgs.msg import Float64MultiArray

from epuck_ros.description import IMU_FRAME
from epuck_ros.model import CAMERA_FOV, GROUND_SENSOR_NAMES, LIGHT_SENSOR_NAMES
from epuck_ros.nodes.robot_ports import STAMP_FIELDS, frame_prefix, quiet_publisher, topic_prefix
from epuck_ros.nodes.serialized import Patch, exact_cdr
from epuck_ros.sensors.camera import camera_matrix
from epuck_ros.sensors.imu import rates_from_gyro_values
from epuck_ros.simulation import Simulation


class SenseError(ValueError):
    """A sense the simulator does not have (the `senses` parameter); the message names it."""


SENSE_POLL = 0.5
"""Wall seconds between two looks at which sense topics have subscribers."""
SENSE_TOPICS = {'camera': 'camera/image_raw', 'ground': 'ground_raw', 'light': 'light_raw', 'imu': 'imu'}
"""Each sense and the topic whose subscribers want it."""
IMU_FIELDS = STAMP_FIELDS + [(f'{vector}.{axis}', 'd') for vector in ('angular_velocity', 'linear_acceleration')
                             for axis in 'xyz']


class ImagePatch:
    """An Image serialised once; `bytes(stamp, pixels)` puts the stamp and the pixels (the message's last field,
    uint8: no padding after it) into a copy."""

    def __init__(self, msg: Image) -> None:
        size = len(msg.data)
        msg.data = bytes(i % 251 for i in range(size))   # a pattern to find
        template = exact_cdr(msg)
        if template[len(template) - size:] != bytes(msg.data):
            raise ValueError('cannot locate the pixels in the serialised Image')
        self._offset = len(template) - size
        self._stamp = Patch(msg, STAMP_FIELDS)

    def bytes(self, stamp: tuple[int, int], pixels: bytes) -> bytes:
        buffer = bytearray(self._stamp.bytes(stamp))
        buffer[self._offset:] = pixels
        return bytes(buffer)


class SensePorts:
    """The sense topics of robot `index`."""

    def __init__(self, node: Node, index: int, name: str, several: bool, stream_qos: QoSProfile,
                 sim: Simulation, frames_prefix: str = '') -> None:
        self.index = index
        topics = topic_prefix(name, several)
        frames = frame_prefix(name, several, frames_prefix)
        width, height = sim.senses.camera_size
        self._image_pub = quiet_publisher(node, Image, topics + SENSE_TOPICS['camera'], stream_qos)
        self._info_pub = quiet_publisher(node, CameraInfo, topics + 'camera/camera_info', stream_qos)
        self._ground_pub = quiet_publisher(node, Float64MultiArray, topics + SENSE_TOPICS['ground'], stream_qos)
        self._light_pub = quiet_publisher(node, Float64MultiArray, topics + SENSE_TOPICS['light'], stream_qos)
        self._imu_pub = quiet_publisher(node, Imu, topics + SENSE_TOPICS['imu'], stream_qos)
        self._publishers = {'camera': self._image_pub, 'ground': self._ground_pub, 'light': self._light_pub,
                            'imu': self._imu_pub}
        self._frames, self._size = frames, (width, height)
        self._made = False
        self.subscribed = {kind: False for kind in SENSE_TOPICS}
        self._info_subscribed = False
        self.publishing = False
        """Some sense topic of this robot has a subscriber: the node calls `publish` after each step."""

    def _make_messages(self) -> None:
        """The messages, serialised once, when a sense of this robot is first wanted (a swarm's robots mostly never
        are: making them for all would slow its start)."""
        frames, (width, height) = self._frames, self._size
        image = Image(height=height, width=width, encoding='rgb8', is_bigendian=0, step=3 * width)
        image.header.frame_id = frames + 'camera'
        image.data = bytes(3 * width * height)
        self._image = ImagePatch(image)
        info = CameraInfo(height=height, width=width, distortion_model='plumb_bob', d=[0.0] * 5,
                          k=camera_matrix(width, height, CAMERA_FOV), r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
        k = info.k
        info.p = [k[0], 0.0, k[2], 0.0, 0.0, k[4], k[5], 0.0, 0.0, 0.0, 1.0, 0.0]
        info.header.frame_id = frames + 'camera'
        self._info = Patch(info, STAMP_FIELDS)
        self._ground = Patch(Float64MultiArray(data=[0.0] * len(GROUND_SENSOR_NAMES)),
                             [(f'data[{i}]', 'd') for i in range(len(GROUND_SENSOR_NAMES))])
        self._light = Patch(Float64MultiArray(data=[0.0] * len(LIGHT_SENSOR_NAMES)),
                            [(f'data[{i}]', 'd') for i in range(len(LIGHT_SENSOR_NAMES))])
        imu = Imu()
        imu.header.frame_id = frames + IMU_FRAME
        imu.orientation_covariance[0] = -1.0   # REP 145: no orientation estimate
        self._imu = Patch(imu, IMU_FIELDS)
        self._made = True

    def update_wants(self, want: Callable[[str, int, bool], None], forced: frozenset[str]) -> None:
        """Tell the simulation which of this robot's senses are wanted now (`forced`: by the parameter)."""
        for kind, publisher in self._publishers.items():
            subscribed = publisher.get_subscription_count() > 0
            if subscribed != self.subscribed[kind]:
                self.subscribed[kind] = subscribed
                want(kind, self.index, subscribed or kind in forced)
        self._info_subscribed = self._info_pub.get_subscription_count() > 0
        self.publishing = self._info_subscribed or any(self.subscribed.values())
        if self.publishing and not self._made:
            self._make_messages()

    def publish(self, sim: Simulation, stamp: tuple[int, int]) -> None:
        """This robot's sense messages for the senses with subscribers (their readings are those of this step)."""
        robot, senses, subscribed = self.index, sim.senses, self.subscribed
        if subscribed['camera'] and senses.images is not None:
            self._image_pub.publish(self._image.bytes(stamp, senses.images[robot].tobytes()))
        if self._info_subscribed:
            self._info_pub.publish(self._info.bytes(stamp))
        if subscribed['ground']:
            self._ground_pub.publish(self._ground.bytes(senses.ground_raw[robot].tolist()))
        if subscribed['light']:
            self._light_pub.publish(self._light.bytes(senses.light_raw[robot].tolist()))
        if subscribed['imu']:
            rates = rates_from_gyro_values(senses.gyro[robot]).tolist()
            self._imu_pub.publish(self._imu.bytes((*stamp, *rates, *senses.accelerometer[robot].tolist())))
